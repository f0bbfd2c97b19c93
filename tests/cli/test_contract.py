"""The command line's contract: ``--json`` documents on stdout, exit code 1 for a refusal and 2 for a usage
error, enumerated choices in ``--help``."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any, get_args

import pytest
from typer.testing import CliRunner, Result

from driftmap.cli import app, camera, data, localise, maps
from driftmap.config import Settings, get_settings
from driftmap.core.imaging.lens import LENS_MODELS
from driftmap.core.mapping.pipeline import MAP_PRESETS
from driftmap.errors import BadInputError
from driftmap.services import maps as map_service
from driftmap.services.users import ROLES
from driftmap.sim.params import RIGS, SIZES
from tests.cli.in_process import point_cli_at

runner = CliRunner()


@pytest.fixture
def empty_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The CLI pointed at an empty data dir."""
    point_cli_at(monkeypatch, Settings(data_dir=tmp_path / "data"))
    yield
    get_settings.cache_clear()


def _json(*args: str) -> Any:
    result = runner.invoke(app, list(args))
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def _refused(*args: str) -> Result:
    return runner.invoke(app, list(args))


class TestJsonOutput:
    def test_site_drive_and_map(self, built_tiny_cli: None) -> None:
        sites = _json("site", "list", "--json")
        assert [s["name"] for s in sites] == ["tiny"] and sites[0]["drives"] > 0
        drives = _json("drive", "list", "tiny", "--json")
        assert {d["kind"] for d in drives} >= {"mapping"}
        assert set(drives[0]) == {"id", "name", "kind", "frames", "fps", "duration_s", "groundings", "truth"}
        shown = _json("map", "show", "tiny", "--json")
        assert shown["version"] >= 1 and shown["stats"]["nodes"] > 0
        assert shown["summary"]["overall"]["count"] == len(shown["residuals"])
        assert {"drive", "frame", "dx_m", "dy_m", "distance_m"} <= set(shown["residuals"][0])

    def test_build_prints_the_new_version(
        self, built_tiny_cli: None, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        """The build itself is the mapping tests' (stood in for here): --json prints its version and figures."""
        built = (
            SimpleNamespace(version=7),
            SimpleNamespace(stats={"frames": 12, "nodes": 5, "odometry_s": 1.5}),
        )
        monkeypatch.setattr(map_service, "build_site_map", lambda *_a, **_k: built)
        monkeypatch.setattr(map_service, "ensure_buildable", lambda *_a: None)
        document = _json("map", "build", "tiny", "--preset", "fast", "--json")
        assert document == {
            "site": "tiny",
            "version": 7,
            "stats": {"frames": 12, "nodes": 5, "odometry_s": 1.5},
        }

    def test_users_and_an_empty_store(self, empty_env: None) -> None:
        assert _json("site", "list", "--json") == []
        assert _json("user", "list", "--json") == []
        assert _json("camera", "profiles", "--json") == []

    def test_a_refused_build_prints_no_document(self, empty_env: None, tmp_path: Path) -> None:
        result = _refused("map", "build", "nowhere", "--json")
        assert result.exit_code == 1 and result.stdout == "" and "nowhere" in result.stderr


class TestMethodChoice:
    def test_the_chosen_methods_reach_the_report(
        self, built_tiny_cli: None, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        """The report itself is the reports tests' (stood in for here): it is given the labels chosen."""
        given: list[object] = []

        def report(*_args: object, methods: object = None, **_kwargs: object) -> object:
            given.append(methods)
            raise BadInputError("stood in")

        monkeypatch.setattr(localise, "run_localisation_report", report)
        chosen = ["--method", "HMM+SESAME+odometry", "--method", "SAD"]
        result = _refused("report", "localisation", "tiny", "--truth", *chosen)
        assert result.exit_code == 1 and "stood in" in result.stderr
        assert given == [["HMM+SESAME+odometry", "SAD"]]


class TestExitCodes:
    def test_refusals_exit_1(self, empty_env: None) -> None:
        result = _refused("drive", "list", "nowhere")
        assert result.exit_code == 1 and "error:" in result.stderr and "Traceback" not in result.output

    def test_usage_errors_exit_2(self, empty_env: None, tmp_path: Path) -> None:
        assert _refused("site", "list", "--no-such-option").exit_code == 2
        assert _refused("map", "build", "tiny", "--preset", "slow").exit_code == 2
        assert _refused("report", "localisation", "tiny", "--truth", "--method", "SIFT").exit_code == 2
        out = tmp_path / "x.csv"
        both = _refused("map", "export", "tiny", "--format", "csv")  # --format without --out
        assert both.exit_code == 2 and "--out" in both.output and not out.exists()


class TestChoices:
    @pytest.mark.parametrize(
        ("command", "shown"),
        [
            (["map", "build"], "paper|fast"),
            (["simulate"], "tiny|small|medium|large"),
            (["drive", "import"], "mapping|localisation"),
            (["user", "add"], "admin|surveyor|viewer"),
            (["camera", "intrinsics"], "pinhole|fisheye"),
            (["map", "export"], "csv|"),
            (["positions", "export"], "csv|geojson|dxf|kml|tum|kitti"),
            (["report", "localisation"], "SAD|SAD+SESAME|HMM+SAD|HMM+SESAME|HMM+SESAME+odometry"),
        ],
    )
    def test_help_lists_the_choices(self, command: list[str], shown: str) -> None:
        result = runner.invoke(app, [*command, "--help"], env={"COLUMNS": "200"})
        assert result.exit_code == 0 and shown in result.output, result.output

    def test_choices_match_what_the_code_accepts(self) -> None:
        assert set(get_args(maps.PresetName)) == set(MAP_PRESETS)
        assert set(get_args(data.SizeName)) == set(SIZES)
        assert set(get_args(data.SimCamera)) == set(RIGS)
        assert set(get_args(camera.LensName)) == set(LENS_MODELS)
        user_add_role = runner.invoke(app, ["user", "add", "--help"], env={"COLUMNS": "200"}).output
        assert "|".join(ROLES) in user_add_role
