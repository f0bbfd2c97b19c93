"""``driftmap vpr match`` end to end on a small generated dataset folder (formats.md)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from driftmap.cli import app
from driftmap.formats.csv_exports import read_place_matches_csv
from driftmap.formats.place_dataset import write_gt_csv
from tests.vpr_factory import noisy, textures

runner = CliRunner()
PLACES = 16


@pytest.fixture
def dataset(tmp_path: Path) -> Path:
    """db/ and query/ with 16 places each (query = a noisy view), gt.csv accepting +-1 place."""
    folder = tmp_path / "place-data"
    db = textures(PLACES, seed=5)
    query = noisy(db, 8.0, seed=6)
    for sub, images in (("db", db), ("query", query)):
        (folder / sub).mkdir(parents=True)
        for i, image in enumerate(images):
            assert cv2.imwrite(str(folder / sub / f"{i:04d}.png"), image)
    pairs = [
        (f"{i:04d}.png", f"{j:04d}.png") for i in range(PLACES) for j in range(PLACES) if abs(i - j) <= 1
    ]
    write_gt_csv(folder / "gt.csv", pairs)
    return folder


def _match(folder: Path, out: Path, *extra: str) -> tuple[int, str]:
    args = ["vpr", "match", "--db", str(folder / "db"), "--query", str(folder / "query"), "--out", str(out)]
    result = runner.invoke(app, [*args, *extra])
    return result.exit_code, result.output


class TestMatch:
    @pytest.mark.parametrize(
        "extra",
        [
            (),
            ("--method", "sad"),
            ("--temporal",),
            ("--temporal", "--online"),
            ("--temporal", "--preset", "mine", "--method", "sesame"),
            ("--temporal", "--any-speed"),
        ],
    )
    def test_writes_one_row_per_query_and_scores(
        self, dataset: Path, tmp_path: Path, extra: tuple[str, ...]
    ) -> None:
        out = tmp_path / "matches.csv"
        code, output = _match(dataset, out, *extra)
        assert code == 0, output
        rows = read_place_matches_csv(out)
        assert [r.query for r in rows] == [f"{i:04d}.png" for i in range(PLACES)]
        assert sum(r.db == r.query for r in rows) >= PLACES - 2
        assert "recall@1" in output and "gt.csv" in output

    @pytest.mark.parametrize(
        ("extra", "says"),
        [
            (("--temporal",), "(sad, route HMM, preset route;"),
            (("--temporal", "--online", "--any-speed"), "(sad, route HMM, online, any speed, preset route;"),
            ((), "(sesame, single image, preset mine;"),
        ],
    )
    def test_defaults_depend_on_temporal(
        self, dataset: Path, tmp_path: Path, extra: tuple[str, ...], says: str
    ) -> None:
        code, output = _match(dataset, tmp_path / "m.csv", *extra)
        assert code == 0, output
        assert says in " ".join(output.split())  # rich wraps long lines

    def test_without_ground_truth(self, dataset: Path, tmp_path: Path) -> None:
        (dataset / "gt.csv").unlink()
        code, output = _match(dataset, tmp_path / "m.csv")
        assert code == 0, output
        assert "recall@1" not in output
        assert len(read_place_matches_csv(tmp_path / "m.csv")) == PLACES


class TestBadInput:
    def test_corrupt_image_is_named(self, dataset: Path, tmp_path: Path) -> None:
        (dataset / "query" / "0003.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
        code, output = _match(dataset, tmp_path / "m.csv")
        assert code == 1
        assert "0003.png" in output and "Traceback" not in output
        assert not (tmp_path / "m.csv").exists()

    def test_image_of_another_size_is_named(self, dataset: Path, tmp_path: Path) -> None:
        cv2.imwrite(str(dataset / "db" / "0007.png"), np.zeros((10, 10), dtype=np.uint8))
        code, output = _match(dataset, tmp_path / "m.csv")
        assert code == 1
        assert "0007.png" in output and "10x10" in output

    def test_gt_naming_a_missing_image(self, dataset: Path, tmp_path: Path) -> None:
        with (dataset / "gt.csv").open("a") as f:
            f.write("0001.png,9999.png\n")
        code, output = _match(dataset, tmp_path / "m.csv")
        assert code == 1
        assert "gt.csv" in output and "9999.png" in output

    def test_empty_folder_and_unknown_method(self, dataset: Path, tmp_path: Path) -> None:
        for image in (dataset / "query").iterdir():
            image.unlink()
        code, output = _match(dataset, tmp_path / "m.csv")
        assert code == 1 and "query" in output and "no images" in output
        code, output = _match(dataset, tmp_path / "m.csv", "--method", "orb")
        assert code == 2 and "orb" in output  # usage: --method takes one of its choices

    def test_route_options_need_temporal(self, dataset: Path, tmp_path: Path) -> None:
        for option in ("--online", "--any-speed"):
            code, output = _match(dataset, tmp_path / "m.csv", option)
            assert code == 2 and option in output and "--temporal" in output
        assert not (tmp_path / "m.csv").exists()
