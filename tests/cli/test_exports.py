"""``driftmap map export`` and ``driftmap positions export`` on the run's real database: files written,
read back, refusals that name the option and write nothing."""

from __future__ import annotations

import io
import json
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import ezdxf
import numpy as np
import pytest
from evo.tools import file_interface
from typer.testing import CliRunner

from driftmap.cli import app
from driftmap.config import get_settings
from driftmap.formats.csv_exports import parse_poses_csv, read_poses_csv
from driftmap.formats.g2o import read_g2o
from driftmap.formats.position_exports import parse_positions_csv
from driftmap.formats.site_crs import SiteCrs
from driftmap.formats.trajectory_exports import COORDINATES_MEMBER, KML_NAMESPACE, PLANE_COORDINATES
from tests.cli.in_process import point_cli_at
from tests.export_site import LOADER, SITE, TRACKS, TRUCK, export_store

runner = CliRunner()


@pytest.fixture
def env(
    tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[None]:
    settings = export_store(tmp_path_factory, tiny_site_dir)
    point_cli_at(monkeypatch, settings)
    yield
    get_settings.cache_clear()


def _run(*args: str) -> str:
    result = runner.invoke(app, list(args))
    assert result.exit_code == 0, result.output
    return result.output


class TestMapExport:
    def test_poses_keeps_its_format_beside_a_format_export(self, env: None, tmp_path: Path) -> None:
        poses, timed = tmp_path / "poses.csv", tmp_path / "timed.csv"
        output = _run("map", "export", SITE, "--poses", str(poses), "--format", "csv", "--out", str(timed))
        assert "map version 1" in output
        assert poses.read_text().splitlines()[0] == "drive,frame,x,y,yaw"
        assert timed.read_text().splitlines()[0] == "drive,frame,t,x,y,yaw"
        plain, with_time = read_poses_csv(poses), read_poses_csv(timed)
        assert [(r.drive, r.frame, r.x_m) for r in plain] == [(r.drive, r.frame, r.x_m) for r in with_time]
        assert all(r.t_s is None for r in plain) and all(r.t_s is not None for r in with_time)

    def test_every_format_is_written(self, env: None, tmp_path: Path) -> None:
        rows = parse_poses_csv(_run_to_text(tmp_path, "csv"), "p.csv")
        assert json.loads(_run_to_text(tmp_path, "geojson"))["driftmap:map_version"] == 1
        assert "<Placemark>" in _run_to_text(tmp_path, "kml")
        dxf = ezdxf.read(io.StringIO(_run_to_text(tmp_path, "dxf", "--nodes", "--closures")))
        assert {"NODES", "CLOSURES", "DRIVE-map-01", "DRIVE-map-02"} <= {
            layer.dxf.name for layer in dxf.layers
        }
        _run("map", "export", SITE, "--format", "g2o", "--out", str(tmp_path / "map.g2o"))
        assert read_g2o(tmp_path / "map.g2o").wTi.shape == (len(rows), 3)
        for fmt, reader in (
            ("tum", file_interface.read_tum_trajectory_file),
            ("kitti", file_interface.read_kitti_poses_file),
        ):
            out = tmp_path / f"map-01.{fmt}.txt"
            _run("map", "export", SITE, "--format", fmt, "--drive", "map-01", "--out", str(out))
            assert reader(str(out)).num_poses == sum(r.drive == "map-01" for r in rows)

    def test_refusals_name_the_option_and_write_nothing(self, env: None, tmp_path: Path) -> None:
        out, poses = tmp_path / "map.tum.txt", tmp_path / "poses.csv"
        result = runner.invoke(
            app, ["map", "export", SITE, "--format", "tum", "--out", str(out), "--poses", str(poses)]
        )
        assert result.exit_code == 1 and "pick one drive" in result.output
        assert not out.exists() and not poses.exists()
        result = runner.invoke(app, ["map", "export", SITE, "--format", "shp", "--out", str(out)])
        assert result.exit_code == 2 and "--format" in result.output
        result = runner.invoke(app, ["map", "export", SITE])
        assert result.exit_code == 2 and "--poses" in result.output
        result = runner.invoke(app, ["map", "export", SITE, "--format", "csv", "--out", str(out), "--nodes"])
        assert result.exit_code == 2 and "dxf" in result.output
        assert list(tmp_path.iterdir()) == []


def _run_to_text(tmp_path: Path, fmt: str, *extra: str) -> str:
    out = tmp_path / f"map.{fmt}"
    _run("map", "export", SITE, "--format", fmt, "--out", str(out), *extra)
    return out.read_text(encoding="utf-8")


class TestPositionsExport:
    def test_all_vehicles_and_one_over_a_range(self, env: None, tmp_path: Path) -> None:
        out = tmp_path / "positions.csv"
        assert "wrote 13 positions" in _run("positions", "export", SITE, "--format", "csv", "--out", str(out))
        rows = parse_positions_csv(out.read_text(), out)
        assert [r.vehicle for r in rows] == [LOADER] * 10 + [TRUCK] * 3
        _run(
            "positions", "export", SITE, "--vehicle", TRUCK, "--since", "50.2", "--until", "60",
            "--format", "tum", "--out", str(tmp_path / "truck.txt"),
        )  # fmt: skip
        trajectory = file_interface.read_tum_trajectory_file(str(tmp_path / "truck.txt"))
        assert list(trajectory.timestamps) == TRACKS[1].t[1:]
        _run("positions", "export", SITE, "--format", "geojson", "--out", str(tmp_path / "p.geojson"))
        features = json.loads((tmp_path / "p.geojson").read_text())["features"]
        assert [f["properties"]["vehicle"] for f in features] == [LOADER, TRUCK]

    def test_refusals(self, env: None, tmp_path: Path) -> None:
        out = tmp_path / "p.csv"
        result = runner.invoke(
            app,
            [
                "positions",
                "export",
                SITE,
                "--since",
                "5",
                "--until",
                "4",
                "--format",
                "csv",
                "--out",
                str(out),
            ],
        )
        assert result.exit_code == 1 and "until" in result.output
        result = runner.invoke(app, ["positions", "export", SITE, "--format", "g2o", "--out", str(out)])
        assert result.exit_code == 2 and "--format" in result.output
        result = runner.invoke(
            app, ["positions", "export", SITE, "--vehicle", "ghost", "--format", "csv", "--out", str(out)]
        )
        assert result.exit_code == 1 and "ghost" in result.output
        assert not out.exists()


def _xy(collection: dict[str, Any]) -> list[np.ndarray]:
    return [np.array(f["geometry"]["coordinates"], dtype=float) for f in collection["features"]]


class TestSiteCrs:
    def test_mine_grid_then_wgs84_then_plane_again(self, built_tiny_cli: None, tmp_path: Path) -> None:
        plane = json.loads(_run_to_text(tmp_path, "geojson"))
        assert plane[COORDINATES_MEMBER] == PLANE_COORDINATES

        grid_args = ["--false-origin", "5000,20000", "--rotation-deg", "90", "--scale", "1.0002"]
        assert "mine grid" in _run("site", "crs", SITE, *grid_args)
        grid = json.loads(_run_to_text(tmp_path, "geojson"))
        assert "mine grid" in grid[COORDINATES_MEMBER]
        to_grid = SiteCrs(None, 5000.0, 20000.0, 90.0, 1.0002).to_grid
        for before, after in zip(_xy(plane), _xy(grid), strict=True):
            np.testing.assert_allclose(after, to_grid(before), atol=1e-6)
        kml = ET.fromstring(_run_to_text(tmp_path, "kml"))
        first = kml.find(f".//{{{KML_NAMESPACE}}}coordinates")
        assert first is not None and first.text is not None
        east, north, _z = (float(v) for v in first.text.split()[0].split(","))
        np.testing.assert_allclose([east, north], _xy(grid)[0][0], atol=1e-6)

        placed = SiteCrs(28355, 321_000.0, 6_123_000.0, 3.0)  # GDA94 / MGA zone 55
        _run(
            "site", "crs", SITE, "--epsg", "28355", "--false-origin", "321000,6123000", "--rotation-deg", "3"
        )
        earth = json.loads(_run_to_text(tmp_path, "geojson"))
        assert "EPSG:28355" in earth[COORDINATES_MEMBER]
        for before, lonlat in zip(_xy(plane), _xy(earth), strict=True):
            assert np.all((lonlat[:, 0] > 144.0) & (lonlat[:, 0] < 146.0))
            assert np.all((lonlat[:, 1] > -36.0) & (lonlat[:, 1] < -34.0))
            np.testing.assert_allclose(placed.from_wgs84(lonlat), before, atol=1e-3)  # back on the floor

        refused = runner.invoke(app, ["site", "crs", SITE, "--false-origin", "12"])
        assert refused.exit_code == 1 and "--false-origin" in refused.output
        _run("site", "crs", SITE, "--clear")
        assert json.loads(_run_to_text(tmp_path, "geojson")) == plane
