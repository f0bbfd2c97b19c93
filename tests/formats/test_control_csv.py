"""Survey control tables: optional station/enabled columns of ``groundings.csv``, a site's control file and
the residuals CSV; each bad cell named by line and field."""

from __future__ import annotations

import math

import pytest

from driftmap.errors import BadInputError
from driftmap.formats.control_csv import (
    ResidualCsvRow,
    control_text,
    parse_control_rows,
    parse_enabled,
    residuals_text,
)
from driftmap.formats.csv_exports import groundings_text, parse_groundings_csv
from driftmap.formats.records import GroundingRow, SiteGroundingRow


class TestDriveGroundings:
    def test_old_files_read_and_are_written_unchanged(self) -> None:
        text = "frame,x,y\n3,1.5,2.5\n"
        rows = parse_groundings_csv(text, "g.csv")
        assert rows == [GroundingRow(3, 1.5, 2.5, station=None, enabled=True)]
        assert groundings_text(rows) == text

    def test_station_and_enabled_round_trip(self) -> None:
        rows = [GroundingRow(3, 1.5, 2.5, "STN-104", True), GroundingRow(9, -1.0, 0.25, None, False)]
        text = groundings_text(rows)
        assert text.splitlines()[0] == "frame,x,y,station,enabled"
        assert parse_groundings_csv(text, "g.csv") == rows

    def test_either_optional_column_alone(self) -> None:
        assert parse_groundings_csv("frame,x,y,station\n1,0,0,A\n", "g")[0].station == "A"
        assert parse_groundings_csv("frame,x,y,enabled\n1,0,0,no\n", "g")[0].enabled is False


class TestControlFile:
    ROWS = (
        SiteGroundingRow("map-01", 3, "STN-1", 1.5, 2.5, True),
        SiteGroundingRow("map-02", 3, None, 101.0, -7.125, False),
    )

    def test_round_trip(self) -> None:
        text = control_text(self.ROWS)
        assert text.splitlines()[0] == "drive,frame,station,x,y,enabled"
        assert [r for _line, r in parse_control_rows(text, "c.csv")] == list(self.ROWS)

    @pytest.mark.parametrize(
        ("row", "field"),
        [
            ("map-01,x,,1,2,true", "frame"),
            ("map-01,-1,,1,2,true", "frame"),
            ("map-01,4,,nan,2,true", "x"),
            ("map-01,4,,1,inf,true", "y"),
            ("map-01,4,,1,2,maybe", "enabled"),
            ("map-01,3,,1,2,true", "frame"),
            (",4,,1,2,true", "drive"),
            ("map-01,4," + "S" * 65 + ",1,2,true", "station"),
        ],
    )
    def test_a_bad_row_is_named(self, row: str, field: str) -> None:
        text = "drive,frame,station,x,y,enabled\nmap-01,3,,0,0,true\n" + row + "\n"
        with pytest.raises(BadInputError) as caught:
            parse_control_rows(text, "c.csv")
        assert (caught.value.file, caught.value.line, caught.value.field) == ("c.csv", 3, field)

    def test_enabled_spellings(self) -> None:
        spelled = {"TRUE": True, "1": True, "yes": True, "": True, "False": False, "0": False, "NO": False}
        assert {k: parse_enabled(k, file="c", line=2) for k in spelled} == spelled


def test_residuals_text_has_its_header_and_blank_for_deleted() -> None:
    text = residuals_text([ResidualCsvRow("map-01", 3, None, 1.0, 2.0, math.sqrt(2.0), None)])
    header, row = text.splitlines()
    assert header == "drive,frame,station,x,y,residual_m,enabled"
    assert row == f"map-01,3,,1.0,2.0,{math.sqrt(2.0)!r},"
