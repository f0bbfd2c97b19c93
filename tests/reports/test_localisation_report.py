"""The localisation report on the tiny simulated site: four methods, a PR figure and a sane table."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.sesame.masks import SESAME_DEFAULT
from driftmap.errors import BadInputError
from driftmap.reports.localisation_report import run_localisation_report
from driftmap.reports.localisation_results import DEFAULT_METHOD, METHODS, condition_of
from driftmap.services import localisation as loc_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services.localisation import RecordedDrive
from driftmap.store.storage import Storage
from tests.localisation_site import SITE, tiny_map_settings

pytestmark = pytest.mark.db  # reads the session's stored tiny map (tests/localisation_site.py)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
MIN_HMM_AUC = 0.7  # HMM methods on the tiny site's clean drive
MAX_MATCHED_ERROR_M = 5.0  # mean node-centre error of the HMM's matched frames, metres
SINGLE_IMAGE_STRIDE = 4  # single-image methods compare the whole map: every 4th frame keeps the test fast


def _latest_map_and_drives(
    tmp_path_factory: pytest.TempPathFactory, site_dir: Path
) -> tuple[LocaliserMap, list[RecordedDrive]]:
    """The tiny site's latest localiser map and its localisation drives."""
    storage = Storage.open(tiny_map_settings(tmp_path_factory, site_dir))
    try:
        with storage.db.session() as session:
            site = site_service.get_site(session, SITE)
            lmap = loc_service.load_localiser_map(session, storage.blobs, site)
            return lmap, loc_service.load_localisation_drives(session, storage.blobs, site)
    finally:
        storage.close()


class TestConditionOf:
    @pytest.mark.parametrize(
        ("name", "condition"),
        [("loc-01", "clean"), ("loc-01-dust2", "dust2"), ("east-water1", "water1"), ("dusty-run", "clean")],
    )
    def test_suffixes(self, name: str, condition: str) -> None:
        assert condition_of(name) == condition


class TestReport:
    def test_tiny_site(
        self, tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, tmp_path: Path
    ) -> None:
        storage = Storage.open(tiny_map_settings(tmp_path_factory, tiny_site_dir))
        try:
            with storage.db.session() as session:
                site = site_service.get_site(session, SITE)
                version = map_service.get_map_version(session, site)
                lmap = loc_service.load_version_localiser_map(session, storage.blobs, version)
                drives = loc_service.load_localisation_drives(session, storage.blobs, site)
                sesame = loc_service.sesame_params_of(version)
        finally:
            storage.close()
        report = run_localisation_report(
            lmap, drives, sesame, tolerance_m=15.0, out_dir=tmp_path, single_image_stride=SINGLE_IMAGE_STRIDE
        )
        assert report.figure is not None and report.figure.read_bytes()[:8] == PNG_MAGIC
        assert report.table_path is not None and report.table_path.read_text().startswith("| condition")
        rows = {(r["condition"], r["method"]): r for r in report.rows()}
        assert set(rows) == {("clean", name) for name, *_ in METHODS}
        frames = drives[0].t_s.size
        for (_cond, method), row in rows.items():
            assert row["frames"] == (
                frames if method.startswith("HMM") else -(-frames // SINGLE_IMAGE_STRIDE)
            )
            assert 0.0 <= float(row["auc"]) <= 1.0
            assert 0.0 <= float(row["recall_at_p100"]) <= float(row["auc"]) + 1e-9  # AP >= recall at P = 1
            assert 0.0 <= float(row["recall_at_p100_confidence"]) <= 1.0
        for name in ("HMM+SAD", "HMM+SESAME", DEFAULT_METHOD):
            assert float(rows[("clean", name)]["auc"]) >= MIN_HMM_AUC
            error = float(rows[("clean", name)]["matched_error_m"])
            assert math.isfinite(error) and error <= MAX_MATCHED_ERROR_M
            assert 0.0 <= float(rows[("clean", name)]["ece"]) <= 1.0
        table = report.table()
        assert "HMM+SESAME" in table and f"{DEFAULT_METHOD}, each drive on its own" in table
        assert drives[0].name in table
        assert (tmp_path / "localisation_reliability.png").read_bytes()[:8] == PNG_MAGIC
        knots = report.calibration()  # None when every frame of the tiny drive was right
        assert knots is None or all(b[1] > a[1] for a, b in itertools.pairwise(knots))

    def test_known_start_puts_the_first_estimate_at_the_start(
        self, tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path
    ) -> None:
        lmap, drives = _latest_map_and_drives(tmp_path_factory, tiny_site_dir)
        report = run_localisation_report(
            lmap, drives, SESAME_DEFAULT, single_image_stride=10_000, known_start=True
        )
        truth = drives[0].truth_xy_m
        assert truth is not None
        start = lmap.centres_m[lmap.nearest_node(*truth[0])]
        for name in ("HMM+SAD", "HMM+SESAME", DEFAULT_METHOD):
            # at the start node: its centre, pulled towards where its best-matching reference was taken (a
            # node's frames lie within the merge radius, 2.5 m, of its centre)
            first_error_m = report.results[("clean", name)].error_m[0]
            assert first_error_m <= float(np.hypot(*(start - truth[0]))) + 2.5
        assert "known start" in report.table()

    def test_a_subset_of_methods(self, tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path) -> None:
        lmap, drives = _latest_map_and_drives(tmp_path_factory, tiny_site_dir)
        report = run_localisation_report(lmap, drives, SESAME_DEFAULT, methods=["HMM+SESAME", DEFAULT_METHOD])
        assert {method for _cond, method in report.results} == {"HMM+SESAME", DEFAULT_METHOD}
        with pytest.raises(BadInputError, match="unknown method"):
            run_localisation_report(lmap, drives, SESAME_DEFAULT, methods=["HMM+ORB"])

    def test_needs_drives_and_positive_tolerance(
        self, tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path
    ) -> None:
        lmap, drives = _latest_map_and_drives(tmp_path_factory, tiny_site_dir)
        with pytest.raises(BadInputError, match="no localisation drive"):
            run_localisation_report(lmap, [], SESAME_DEFAULT)
        with pytest.raises(BadInputError, match="positive"):
            run_localisation_report(lmap, drives, SESAME_DEFAULT, tolerance_m=0.0)
