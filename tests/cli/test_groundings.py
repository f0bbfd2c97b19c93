"""``driftmap groundings export|import`` and the residual summary of ``driftmap map show`` on a private copy
of the built tiny site: files written and read back, a bad row named, nothing half-written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from driftmap.cli import app

runner = CliRunner()


def _run(*args: str, code: int = 0) -> str:
    result = runner.invoke(app, list(args))
    assert result.exit_code == code, result.output
    return result.output


class TestControlFile:
    def test_export_edit_import(self, built_tiny_cli: None, tmp_path: Path) -> None:
        out = tmp_path / "control.csv"
        assert "wrote" in _run("groundings", "export", "tiny", "--out", str(out))
        header, *rows = out.read_text().splitlines()
        assert header == "drive,frame,station,x,y,enabled" and len(rows) >= 2
        drive, frame, _station, x, y, _enabled = rows[0].split(",")
        rows[0] = ",".join([drive, frame, "STN-104", x, y, "false"])
        edited = tmp_path / "edited.csv"
        edited.write_text("\n".join([header, *rows]) + "\n")
        assert f"imported {len(rows)} groundings" in _run("groundings", "import", "tiny", str(edited))
        _run("groundings", "export", "tiny", "--out", str(out))
        assert out.read_text() == edited.read_text()

    def test_a_bad_row_is_named_and_nothing_changes(self, built_tiny_cli: None, tmp_path: Path) -> None:
        before = tmp_path / "before.csv"
        _run("groundings", "export", "tiny", "--out", str(before))
        bad = tmp_path / "bad.csv"
        bad.write_text(before.read_text() + "nowhere,1,,0.0,0.0,true\n")
        line = len(before.read_text().splitlines()) + 1
        output = _run("groundings", "import", "tiny", str(bad), code=1)
        assert f"bad.csv:{line} field 'drive'" in output and "nowhere" in output
        after = tmp_path / "after.csv"
        _run("groundings", "export", "tiny", "--out", str(after))
        assert after.read_text() == before.read_text()


def test_map_show_prints_the_residual_summary(built_tiny_cli: None) -> None:
    output = _run("map", "show", "tiny")
    assert "RMS m" in output and "mean m" in output and "max m" in output
    assert "all" in output


def test_the_residuals_csv_matches_map_show(built_tiny_cli: None, tmp_path: Path) -> None:
    out = tmp_path / "residuals.csv"
    assert "of map version 1 of 'tiny'" in _run("groundings", "residuals", "tiny", "--out", str(out))
    header, *lines = out.read_text().splitlines()
    assert header == "drive,frame,station,x,y,residual_m,enabled"
    shown = json.loads(_run("map", "show", "tiny", "--json"))["residuals"]
    by_frame = {(r["drive"], r["frame"]): r["distance_m"] for r in shown}
    written = {(c[0], int(c[1])): float(c[5]) for c in (line.split(",") for line in lines)}
    assert written == pytest.approx(by_frame) and len(written) == len(shown) > 0
    refused = runner.invoke(app, ["groundings", "residuals", "tiny", "--version", "9", "--out", str(out)])
    assert refused.exit_code == 1 and "9" in refused.output
