"""Tests of driftmap.formats.place_dataset: listing in name order and checking gt.csv."""

from __future__ import annotations

from pathlib import Path

import pytest

from driftmap.errors import BadInputError
from driftmap.formats.place_dataset import read_place_dataset, write_gt_csv
from tests.formats.builders import make_png


@pytest.fixture
def dataset(tmp_path: Path) -> Path:
    root = tmp_path / "ds"
    for sub, names in (("db", ["b10.png", "b02.png", "b01.JPG"]), ("query", ["q2.png", "q1.png"])):
        (root / sub).mkdir(parents=True)
        for i, name in enumerate(names):
            (root / sub / name).write_bytes(make_png(i))
    (root / "db" / "notes.txt").write_text("ignored")
    (root / "db" / ".hidden.png").write_bytes(b"")
    write_gt_csv(root / "gt.csv", [("q1.png", "b01.JPG"), ("q1.png", "b02.png"), ("q2.png", "b10.png")])
    return root


class TestRead:
    def test_files_in_sorted_name_order(self, dataset: Path) -> None:
        ds = read_place_dataset(dataset)
        assert [p.name for p in ds.db_files] == ["b01.JPG", "b02.png", "b10.png"]
        assert [p.name for p in ds.query_files] == ["q1.png", "q2.png"]
        assert ds.gt == [("q1.png", "b01.JPG"), ("q1.png", "b02.png"), ("q2.png", "b10.png")]

    def test_gt_optional_on_request(self, dataset: Path) -> None:
        (dataset / "gt.csv").unlink()
        assert read_place_dataset(dataset, require_gt=False).gt == []
        with pytest.raises(BadInputError, match="missing"):
            read_place_dataset(dataset)


class TestErrors:
    @pytest.mark.parametrize(
        ("text", "line", "field", "words"),
        [
            ("query,db\nq9.png,b01.JPG\n", 2, "query", "q9.png"),
            ("query,db\nq1.png,b01.JPG\nq1.png,nope.png\n", 3, "db", "nope.png"),
            ("query,db\nq1.png,b01.JPG\nq1.png,b01.JPG\n", 3, "db", "twice"),
            ("query,database\n", 1, "db", "header"),
            ("query,db\nq1.png,\n", 2, "db", "empty"),
        ],
    )
    def test_bad_gt(self, dataset: Path, text: str, line: int, field: str, words: str) -> None:
        (dataset / "gt.csv").write_text(text)
        with pytest.raises(BadInputError) as info:
            read_place_dataset(dataset)
        assert (info.value.file, info.value.line, info.value.field) == (str(dataset / "gt.csv"), line, field)
        assert words in info.value.reason

    def test_missing_query_folder(self, dataset: Path) -> None:
        for f in (dataset / "query").iterdir():
            f.unlink()
        (dataset / "query").rmdir()
        with pytest.raises(BadInputError, match="query/ folder is missing"):
            read_place_dataset(dataset)

    def test_db_without_images(self, dataset: Path) -> None:
        for f in (dataset / "db").glob("*.*"):
            f.unlink()
        with pytest.raises(BadInputError, match="no images"):
            read_place_dataset(dataset)

    def test_missing_folder(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match="does not exist"):
            read_place_dataset(tmp_path / "nothing")
