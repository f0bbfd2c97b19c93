"""Tests of driftmap.formats.position_exports: the positions CSV written and read back, and positions as
tracks."""

from __future__ import annotations

from pathlib import Path

import pytest

from driftmap.errors import BadInputError
from driftmap.formats.position_exports import (
    PositionRow,
    parse_positions_csv,
    positions_text,
    tracks_from_positions,
    write_positions_csv,
)

POSITIONS = [
    PositionRow("lhd-1", 100.0, 10.5, 20.25, 0.5, 3, 0.9, True, False, 1.5),
    PositionRow("lhd-1", 100.5, 11.0, 20.5, None, 4, 0.2, False, True, None),
    PositionRow("truck, 2", 7.0, -5.0, 1.0, -2.0, 0, 0.5, True, False, -0.25),
]


class TestCsv:
    def test_positions_read_back(self, tmp_path: Path) -> None:
        path = tmp_path / "positions.csv"
        write_positions_csv(path, POSITIONS)
        lines = path.read_text(encoding="utf-8").splitlines()
        assert lines[0] == "vehicle,t,x,y,yaw,node,confidence,matched,lost,speed"
        assert lines[2] == "lhd-1,100.5,11.0,20.5,,4,0.2,0,1,"
        assert lines[3].startswith('"truck, 2",7.0,')
        assert parse_positions_csv(path.read_text(encoding="utf-8"), path) == POSITIONS

    def test_flags_must_be_0_or_1(self) -> None:
        text = positions_text(POSITIONS[:1]).replace(",1,0,", ",yes,0,")
        with pytest.raises(BadInputError) as caught:
            parse_positions_csv(text, "p.csv")
        assert (caught.value.line, caught.value.field) == (2, "matched")

    def test_bad_cells_name_line_and_column(self) -> None:
        text = positions_text(POSITIONS).replace("100.5", "soon")
        with pytest.raises(BadInputError) as caught:
            parse_positions_csv(text, "p.csv")
        assert (caught.value.file, caught.value.line, caught.value.field) == ("p.csv", 3, "t")

    def test_writer_refuses_nan_and_padded_names(self) -> None:
        with pytest.raises(ValueError, match="finite"):
            positions_text([PositionRow("a", float("nan"), 0.0, 0.0, None, 0, 0.5, True, False)])
        with pytest.raises(ValueError, match="padded"):
            positions_text([PositionRow(" a", 0.0, 0.0, 0.0, None, 0, 0.5, True, False)])


class TestTracks:
    def test_one_track_per_vehicle(self) -> None:
        tracks = tracks_from_positions(POSITIONS)
        assert [(t.name, t.kind, len(t.poses)) for t in tracks] == [
            ("lhd-1", "vehicle", 2),
            ("truck, 2", "vehicle", 1),
        ]
        assert tracks[0].poses[1].yaw_rad is None and tracks[0].poses[1].frame is None
        assert [p.t_s for p in tracks[0].poses] == [100.0, 100.5]
