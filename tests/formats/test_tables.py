"""Tests of driftmap.formats.tables: strict cells, line numbers, exact float text."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from driftmap.errors import BadInputError
from driftmap.formats.tables import (
    decode_text,
    format_float,
    parse_float,
    parse_int,
    read_table,
    table_text,
    write_text_atomic,
)

FINITE = st.floats(allow_nan=False, allow_infinity=False)


class TestNumbers:
    @given(FINITE)
    def test_floats_round_trip_exactly(self, value: float) -> None:
        back = parse_float(format_float(value), file="f", line=2, field="x")
        assert back == value and math.copysign(1, back) == math.copysign(1, value)

    @pytest.mark.parametrize(
        "text", ["nan", "NaN", "inf", "-Infinity", "1e999", "1_0", "0x10", "", "1,5", "e5"]
    )
    def test_refused_floats(self, text: str) -> None:
        with pytest.raises(BadInputError) as info:
            parse_float(text, file="f.csv", line=7, field="t")
        assert (info.value.file, info.value.line, info.value.field) == ("f.csv", 7, "t")

    @pytest.mark.parametrize("text", ["1.0", "1_000", "", "0x1", "1e3", "١"])
    def test_refused_ints(self, text: str) -> None:
        with pytest.raises(BadInputError, match="integer"):
            parse_int(text, file="f.csv", line=3, field="frame")

    @pytest.mark.parametrize(("text", "value"), [("1.", 1.0), (".5", 0.5), ("-2e-3", -0.002), ("+7", 7.0)])
    def test_accepted_floats(self, text: str, value: float) -> None:
        assert parse_float(text, file="f", line=2, field="x") == value

    def test_format_refuses_non_finite(self) -> None:
        with pytest.raises(ValueError, match="yaw"):
            format_float(math.nan, field="yaw")


class TestTable:
    def test_quoted_cells_round_trip(self) -> None:
        text = table_text(("query", "db"), [["a,b.png", 'say "x".png']])
        _, rows = read_table(text, "f", [("query", "db")])
        assert rows[0].cells == {"query": "a,b.png", "db": 'say "x".png'}

    def test_not_utf8_names_the_line(self) -> None:
        with pytest.raises(BadInputError) as info:
            decode_text(b"frame,t\n0,0\n\xff,1\n", "frames.csv")
        assert info.value.line == 3

    def test_bom_is_dropped(self) -> None:
        header, _ = read_table(decode_text(b"\xef\xbb\xbfframe,t\n", "f"), "f", [("frame", "t")])
        assert header == ("frame", "t")

    @given(st.text(max_size=200))
    def test_garbage_gives_bad_input_or_rows(self, text: str) -> None:
        try:
            _, rows = read_table(text, "f", [("a", "b")])
        except BadInputError as exc:
            assert exc.file == "f" and exc.line is not None and exc.line >= 1
        else:
            assert all(set(r.cells) == {"a", "b"} for r in rows)

    def test_atomic_write_leaves_no_temporary(self, tmp_path: Path) -> None:
        target = tmp_path / "out.csv"
        write_text_atomic(target, "a\n")
        write_text_atomic(target, "b\n")
        assert target.read_text() == "b\n"
        assert [p.name for p in target.parent.iterdir()] == ["out.csv"]
