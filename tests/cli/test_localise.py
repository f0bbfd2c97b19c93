"""``driftmap localise`` and ``driftmap report localisation`` end to end on the run's real database."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from driftmap.cli import app
from driftmap.config import get_settings
from driftmap.formats.csv_exports import read_localisation_csv
from driftmap.formats.drive_folder import read_drive_folder
from tests.cli.in_process import point_cli_at
from tests.drive_factory import write_test_drive
from tests.localisation_site import SITE, loc_drive_dir, tiny_map_settings

runner = CliRunner()
MAX_NODE_OFFSET_M = 5.0  # a floor point is within this of its nearest node's centre on the tiny map


@pytest.fixture
def tiny_env(
    tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[Path]:
    settings = tiny_map_settings(tmp_path_factory, tiny_site_dir)
    point_cli_at(monkeypatch, settings)
    yield settings.data_dir
    get_settings.cache_clear()


class TestLocalise:
    def test_writes_one_row_per_frame(self, tiny_env: Path, tiny_site_dir: Path, tmp_path: Path) -> None:
        drive = loc_drive_dir(tiny_site_dir)
        out = tmp_path / "est.csv"
        result = runner.invoke(app, ["localise", SITE, str(drive), "--out", str(out)])
        assert result.exit_code == 0, result.output
        assert "map version 1" in result.output
        rows = read_localisation_csv(out)
        frames = [f.frame for f in read_drive_folder(drive).frames]
        assert [r.frame for r in rows] == frames
        assert sum(r.matched for r in rows) > len(rows) // 2

    def test_holistic_single_image(self, tiny_env: Path, tiny_site_dir: Path, tmp_path: Path) -> None:
        drive = loc_drive_dir(tiny_site_dir)
        out = tmp_path / "est.csv"
        args = ["localise", SITE, str(drive), "--out", str(out), "--no-sesame", "--no-temporal"]
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        rows = read_localisation_csv(out)
        assert len(rows) == len(read_drive_folder(drive).frames)
        assert all(0.0 <= r.score <= 1.0 for r in rows)

    def test_known_start(self, tiny_env: Path, tiny_site_dir: Path, tmp_path: Path) -> None:
        drive = loc_drive_dir(tiny_site_dir)
        first = read_drive_folder(drive).frames[0]
        assert first.x_m is not None and first.y_m is not None
        out = tmp_path / "est.csv"
        start = f"{first.x_m:.2f},{first.y_m:.2f}"
        result = runner.invoke(app, ["localise", SITE, str(drive), "--out", str(out), "--start", start])
        assert result.exit_code == 0, result.output
        row = read_localisation_csv(out)[0]
        assert math.hypot(row.x_m - first.x_m, row.y_m - first.y_m) < MAX_NODE_OFFSET_M  # its start's node

    @pytest.mark.parametrize(
        ("start", "says", "code"),
        [  # what --start cannot be read as is a usage error (2), a start off the map a refusal (1)
            ("12.5", "expected 'X,Y'", 2),
            ("a,b", "expected 'X,Y'", 2),
            ("nan,3", "finite", 2),
            ("1e7,1e7", "from the map's nearest node", 1),
        ],
    )
    def test_bad_start_is_refused_before_anything_is_written(
        self, tiny_env: Path, tiny_site_dir: Path, tmp_path: Path, start: str, says: str, code: int
    ) -> None:
        out = tmp_path / "est.csv"
        args = ["localise", SITE, str(loc_drive_dir(tiny_site_dir)), "--out", str(out), "--start", start]
        result = runner.invoke(app, args)
        assert result.exit_code == code
        assert says in result.output and "start" in result.output
        assert not out.exists()

    def test_bad_drive_folder_names_the_file(self, tiny_env: Path, tmp_path: Path) -> None:
        drive = tmp_path / "broken"
        write_test_drive(drive, frames=5)
        frames_csv = drive / "frames.csv"
        lines = frames_csv.read_text().splitlines()
        lines[3] = "2,not-a-time"
        frames_csv.write_text("\n".join(lines) + "\n")
        result = runner.invoke(app, ["localise", SITE, str(drive), "--out", str(tmp_path / "e.csv")])
        assert result.exit_code == 1
        assert "frames.csv" in result.output and ":4" in result.output
        assert not (tmp_path / "e.csv").exists()

    def test_missing_drive_folder(self, tiny_env: Path, tmp_path: Path) -> None:
        result = runner.invoke(
            app, ["localise", SITE, str(tmp_path / "nowhere"), "--out", str(tmp_path / "e.csv")]
        )
        assert result.exit_code == 1
        assert "nowhere" in result.output

    def test_unknown_map_version(self, tiny_env: Path, tiny_site_dir: Path, tmp_path: Path) -> None:
        result = runner.invoke(
            app,
            [
                "localise",
                SITE,
                str(loc_drive_dir(tiny_site_dir)),
                "--out",
                str(tmp_path / "e.csv"),
                "--map-version",
                "9",
            ],
        )
        assert result.exit_code == 1
        assert "version 9" in result.output


class TestReportCommand:
    def test_needs_truth_flag(self, tiny_env: Path) -> None:
        result = runner.invoke(app, ["report", "localisation", SITE])
        assert result.exit_code == 2
        assert "--truth" in result.output
