"""The typer CLI end to end on real SQLite files: parse, call services, print, exit codes."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import ezdxf
import pytest
from typer.testing import CliRunner

from driftmap.cli import app
from driftmap.config import get_settings
from tests.drive_factory import write_test_drive

runner = CliRunner()


@pytest.fixture
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    data = tmp_path / "data"
    monkeypatch.setenv("DRIFTMAP_DATA_DIR", str(data))
    monkeypatch.delenv("DRIFTMAP_DATABASE_URL", raising=False)
    get_settings.cache_clear()
    yield data
    get_settings.cache_clear()


def _survey(path: Path) -> Path:
    doc = ezdxf.new("R2000")
    doc.header["$INSUNITS"] = 6
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (100, 0), (100, 5), (0, 5)], close=True, dxfattribs={"layer": "WALLS"})
    msp.add_line((0, 2.5), (100, 2.5), dxfattribs={"layer": "CENTRELINE"})
    doc.saveas(path)
    return path


class TestSiteAndDrives:
    def test_create_import_list_export(self, data_dir: Path, tmp_path: Path) -> None:
        survey = _survey(tmp_path / "survey.dxf")
        drives = tmp_path / "drives"
        write_test_drive(drives / "a", name="east-1", frames=7)
        write_test_drive(drives / "b", name="west-1", frames=5, seed=3)
        result = runner.invoke(
            app, ["site", "create", "demo", "--survey", str(survey), "--drives", str(drives)]
        )
        assert result.exit_code == 0, result.output
        assert "CENTRELINE" in result.output and "WALLS" in result.output
        assert (data_dir / "driftmap.sqlite3").is_file() == (get_settings().database_url is None)

        listing = runner.invoke(app, ["drive", "list", "demo"])
        assert listing.exit_code == 0, listing.output
        assert "east-1" in listing.output and "west-1" in listing.output

        out = tmp_path / "exported"
        exported = runner.invoke(app, ["drive", "export", "demo", "east-1", str(out)])
        assert exported.exit_code == 0, exported.output
        assert (out / "frames.csv").read_bytes() == (drives / "a" / "frames.csv").read_bytes()
        assert len(list((out / "frames").iterdir())) == 7

        sites = runner.invoke(app, ["site", "list"])
        assert "demo" in sites.output

    def test_bad_input_exits_1_with_the_file_named(self, data_dir: Path, tmp_path: Path) -> None:
        survey = _survey(tmp_path / "survey.dxf")
        assert runner.invoke(app, ["site", "create", "demo", "--survey", str(survey)]).exit_code == 0
        bad = write_test_drive(tmp_path / "bad", frames=4)
        (bad / "frames.csv").write_text("frame,t,x,y,yaw\n0,0.0,,,\n1,0.1,,,\n2,0.1,,,\n3,0.3,,,\n")
        result = runner.invoke(app, ["drive", "import", "demo", str(bad)])
        assert result.exit_code == 1
        assert "frames.csv:4" in result.output
        assert "Traceback" not in result.output
        assert "east-mapping-1" not in runner.invoke(app, ["drive", "list", "demo"]).output

    def test_unknown_site_and_missing_survey(self, data_dir: Path, tmp_path: Path) -> None:
        result = runner.invoke(app, ["drive", "list", "nowhere"])
        assert result.exit_code == 1 and "nowhere" in result.output
        result = runner.invoke(app, ["site", "create", "x", "--survey", str(tmp_path / "missing.dxf")])
        assert result.exit_code == 2 and "missing.dxf" in result.output

    def test_db_upgrade_and_help(self, data_dir: Path) -> None:
        assert runner.invoke(app, ["db", "upgrade"]).exit_code == 0
        help_text = runner.invoke(app, ["--help"]).output
        for command in ("simulate", "site", "drive", "db"):
            assert command in help_text


class TestMapping:
    @pytest.mark.slow
    def test_build_show_export_and_table_one(
        self, data_dir: Path, tmp_path: Path, tiny_site_dir: Path
    ) -> None:
        created = runner.invoke(
            app,
            [
                "site",
                "create",
                "tiny",
                "--survey",
                str(tiny_site_dir / "survey.dxf"),
                "--drives",
                str(tiny_site_dir / "drives"),
            ],
        )
        assert created.exit_code == 0, created.output
        built = runner.invoke(app, ["map", "build", "tiny", "--preset", "fast"])
        assert built.exit_code == 0, built.output
        assert "map version 1" in built.output
        again = runner.invoke(
            app, ["map", "build", "tiny", "--preset", "fast"]
        )  # nothing changed: all reused
        assert again.exit_code == 0, again.output
        assert "map version 2" in again.output and "odometry of 3 of 3 drive segments reused" in again.output
        assert re.search(r"loop-closure scores of (\d+) of \1 keyframes", again.output), again.output

        shown = runner.invoke(app, ["map", "show", "tiny"])
        assert shown.exit_code == 0, shown.output
        assert "map-01" in shown.output and "distance m" in shown.output

        poses = tmp_path / "poses.csv"
        exported = runner.invoke(app, ["map", "export", "tiny", "--version", "1", "--poses", str(poses)])
        assert exported.exit_code == 0, exported.output
        lines = poses.read_text().splitlines()
        assert lines[0] == "drive,frame,x,y,yaw"
        mapping_frames = sum(
            len((d / "frames.csv").read_text().splitlines()) - 1
            for d in (tiny_site_dir / "drives").glob("map-*")
        )
        assert len(lines) - 1 == mapping_frames

        report = runner.invoke(
            app, ["report", "mapping", "tiny", "--truth", "--preset", "fast", "--out", str(tmp_path)]
        )
        assert report.exit_code == 0, report.output
        for label in ("visual odometry", "loop closure", "groundings", "full system"):
            assert label in report.output
        assert (tmp_path / "mapping.png").stat().st_size > 10_000

    def test_map_commands_explain_missing_pieces(self, data_dir: Path, tmp_path: Path) -> None:
        survey = _survey(tmp_path / "survey.dxf")
        assert runner.invoke(app, ["site", "create", "bare", "--survey", str(survey)]).exit_code == 0
        result = runner.invoke(app, ["map", "show", "bare"])
        assert result.exit_code == 1 and "map build bare" in result.output
        result = runner.invoke(app, ["map", "build", "bare"])
        assert result.exit_code == 1 and "no grounding" in result.output
        result = runner.invoke(app, ["report", "mapping", "bare"])
        assert result.exit_code == 2 and "--truth" in result.output


class TestSettings:
    @pytest.mark.parametrize(
        ("variable", "value"), [("DRIFTMAP_LOG_LEVEL", "verbose"), ("DRIFTMAP_HISTORY_FULL_DAYS", "a week")]
    )
    def test_a_setting_that_does_not_parse_is_named(
        self, monkeypatch: pytest.MonkeyPatch, variable: str, value: str
    ) -> None:
        monkeypatch.setenv(variable, value)
        get_settings.cache_clear()
        try:
            result = runner.invoke(app, ["site", "list"])
        finally:
            monkeypatch.delenv(variable)
            get_settings.cache_clear()
        assert result.exit_code == 2 and f"error: {variable}:" in result.output
        assert "Traceback" not in result.output
