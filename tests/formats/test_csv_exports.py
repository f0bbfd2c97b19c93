"""Tests of driftmap.formats.csv_exports: poses, localisation, place matches and groundings CSVs."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import (
    LocalisationRow,
    PlaceMatchRow,
    PoseRow,
    groundings_text,
    localisation_text,
    parse_groundings_csv,
    parse_localisation_csv,
    parse_place_matches_csv,
    parse_poses_csv,
    place_matches_text,
    poses_text,
    read_groundings_csv,
    read_localisation_csv,
    read_place_matches_csv,
    read_poses_csv,
    write_groundings_csv,
    write_localisation_csv,
    write_place_matches_csv,
    write_poses_csv,
)
from driftmap.formats.records import GroundingRow

FINITE = st.floats(allow_nan=False, allow_infinity=False)
NAMES = st.text(st.characters(blacklist_categories=("Cs", "Cc", "Zs", "Zl", "Zp")), min_size=1, max_size=12)
FRAMES = st.integers(0, 10**9)

Parser = Callable[[str, str], list[Any]]
PARSERS: list[Parser] = [
    parse_poses_csv,
    parse_localisation_csv,
    parse_place_matches_csv,
    parse_groundings_csv,
]
HEADERS = ["drive,frame,x,y,yaw", "frame,node,x,y,score,matched", "query,db,score", "frame,x,y"]


class TestExamples:
    def test_poses(self, tmp_path: Path) -> None:
        rows = [PoseRow("east, 1", 0, 12.31, -4.02, 1.5708), PoseRow("west", 0, 0.1 + 0.2, 1e-300, -3.0)]
        write_poses_csv(tmp_path / "poses.csv", rows)
        text = (tmp_path / "poses.csv").read_text()
        assert text.splitlines()[:2] == ["drive,frame,x,y,yaw", '"east, 1",0,12.31,-4.02,1.5708']
        assert read_poses_csv(tmp_path / "poses.csv") == rows

    def test_poses_with_time(self, tmp_path: Path) -> None:
        rows = [PoseRow("east", 0, 12.31, -4.02, 1.5708, 0.0), PoseRow("east", 1, 12.5, -4.0, 1.5, 0.1)]
        write_poses_csv(tmp_path / "poses.csv", rows, with_time=True)
        text = (tmp_path / "poses.csv").read_text()
        assert text.splitlines()[:2] == ["drive,frame,t,x,y,yaw", "east,0,0.0,12.31,-4.02,1.5708"]
        assert read_poses_csv(tmp_path / "poses.csv") == rows
        assert poses_text(rows).splitlines()[1] == "east,0,12.31,-4.02,1.5708"  # the t-less file as before
        with pytest.raises(ValueError, match="no time"):
            poses_text([PoseRow("east", 0, 0.0, 0.0, 0.0)], with_time=True)

    def test_localisation(self, tmp_path: Path) -> None:
        rows = [
            LocalisationRow(0, 17, 1.5, 2.5, 0.25, True, 1.5, -0.5, True, 0.75),
            LocalisationRow(1, 3, 0.0, 0.0, 0.0, False),
        ]
        write_localisation_csv(tmp_path / "loc.csv", rows)
        assert (tmp_path / "loc.csv").read_text().splitlines() == [
            "frame,node,x,y,score,matched,yaw,speed,odometry,x_paper",
            "0,17,1.5,2.5,0.25,1,1.5,-0.5,1,0.75",
            "1,3,0.0,0.0,0.0,0,,,0,",
        ]
        assert read_localisation_csv(tmp_path / "loc.csv") == rows

    def test_localisation_first_version_is_still_read(self, tmp_path: Path) -> None:
        (tmp_path / "old.csv").write_text("frame,node,x,y,score,matched\n0,17,1.5,2.5,0.5,1\n")
        assert read_localisation_csv(tmp_path / "old.csv") == [LocalisationRow(0, 17, 1.5, 2.5, 0.5, True)]

    def test_localisation_flags_are_0_or_1(self) -> None:
        text = "frame,node,x,y,score,matched,yaw,speed,odometry,x_paper\n0,1,0.0,0.0,0.5,1,,,yes,\n"
        with pytest.raises(BadInputError, match="odometry"):
            parse_localisation_csv(text, "l.csv")

    def test_place_matches(self, tmp_path: Path) -> None:
        rows = [PlaceMatchRow("q 001.png", "db,7.png", -1234.0)]
        write_place_matches_csv(tmp_path / "pr.csv", rows)
        assert read_place_matches_csv(tmp_path / "pr.csv") == rows

    def test_groundings(self, tmp_path: Path) -> None:
        rows = [GroundingRow(0, 12.0, -4.0), GroundingRow(40, 1 / 3, 2.0)]
        write_groundings_csv(tmp_path / "g.csv", rows)
        assert (tmp_path / "g.csv").read_text() == "frame,x,y\n0,12.0,-4.0\n40,0.3333333333333333,2.0\n"
        assert read_groundings_csv(tmp_path / "g.csv") == rows

    def test_writers_refuse_nan(self) -> None:
        with pytest.raises(ValueError, match="score"):
            place_matches_text([PlaceMatchRow("a", "b", float("nan"))])

    def test_writers_refuse_padded_names(self) -> None:
        with pytest.raises(ValueError, match="drive"):
            poses_text([PoseRow(" east", 0, 0.0, 0.0, 0.0)])


class TestErrors:
    @pytest.mark.parametrize(
        ("parser", "text", "line", "field", "words"),
        [
            (parse_poses_csv, "drive,frame,x,y\n", 1, "yaw", "header"),
            (parse_poses_csv, "drive,frame,x,y,yaw\na,0,1,2,3\na,0,1,2,3\n", 3, "frame", "twice"),
            (parse_poses_csv, "drive,frame,x,y,yaw\n,0,1,2,3\n", 2, "drive", "empty"),
            (parse_poses_csv, "drive,frame,x,y,yaw\na,0,1,2,inf\n", 2, "yaw", "finite"),
            (parse_localisation_csv, "frame,node,x,y,score,matched\n0,1,2,3,4,yes\n", 2, "matched", "0 or 1"),
            (parse_localisation_csv, "frame,node,x,y,score,matched\n0,n1,2,3,4,1\n", 2, "node", "integer"),
            (
                parse_localisation_csv,
                "frame,node,x,y,score,matched\n0,1,2,3,4,1\n0,1,2,3,4,1\n",
                3,
                "frame",
                "twice",
            ),
            (parse_place_matches_csv, "query,db,score\na,b,NaN\n", 2, "score", "finite"),
            (parse_place_matches_csv, "query,db,score\na,b,1\na,c,2\n", 3, "query", "twice"),
            (parse_groundings_csv, "frame,x,y\n1,2\n", 2, "y", "cells"),
        ],
    )
    def test_message_names_file_line_and_field(
        self, parser: Parser, text: str, line: int, field: str, words: str
    ) -> None:
        with pytest.raises(BadInputError) as info:
            parser(text, "out.csv")
        assert (info.value.file, info.value.line, info.value.field) == ("out.csv", line, field)
        assert words in info.value.reason
        assert str(info.value).startswith(f"out.csv:{line} field '{field}'")


class TestProperties:
    @given(st.lists(st.tuples(NAMES, FRAMES, FINITE, FINITE, FINITE), max_size=10, unique_by=lambda t: t[:2]))
    def test_poses_round_trip(self, values: list[tuple[str, int, float, float, float]]) -> None:
        rows = [PoseRow(*v) for v in values]
        assert parse_poses_csv(poses_text(rows), "p.csv") == rows

    @given(
        st.lists(
            st.tuples(FRAMES, FRAMES, FINITE, FINITE, FINITE, st.booleans()),
            max_size=10,
            unique_by=lambda t: t[0],
        )
    )
    def test_localisation_round_trip(self, values: list[tuple[int, int, float, float, float, bool]]) -> None:
        rows = [LocalisationRow(*v) for v in values]
        text = localisation_text(rows)
        assert parse_localisation_csv(text, "l.csv") == rows
        assert localisation_text(parse_localisation_csv(text, "l.csv")) == text

    @given(st.lists(st.tuples(NAMES, NAMES, FINITE), max_size=10, unique_by=lambda t: t[0]))
    def test_place_matches_round_trip(self, values: list[tuple[str, str, float]]) -> None:
        rows = [PlaceMatchRow(*v) for v in values]
        assert parse_place_matches_csv(place_matches_text(rows), "m.csv") == rows

    @given(st.lists(st.tuples(FRAMES, FINITE, FINITE), max_size=10, unique_by=lambda t: t[0]))
    def test_groundings_round_trip(self, values: list[tuple[int, float, float]]) -> None:
        rows = [GroundingRow(*v) for v in values]
        assert parse_groundings_csv(groundings_text(rows), "g.csv") == rows

    @settings(max_examples=300)
    @given(st.sampled_from(range(4)), st.lists(st.text(max_size=40), max_size=5))
    def test_garbage_lines_give_bad_input_only(self, which: int, lines: list[str]) -> None:
        text = HEADERS[which] + "\n" + "\n".join(lines)
        try:
            PARSERS[which](text, "x.csv")
        except BadInputError as exc:
            assert exc.file == "x.csv" and exc.line is not None
