"""Survey layers simplified at upload: stored with the plan, served from the store, gone with it (real SQLite)."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from ezdxf.filemanagement import new as new_dxf
from sqlalchemy import func, inspect, select

from driftmap.errors import BadInputError, PayloadTooLargeError
from driftmap.formats.survey_dxf import DxfLimits
from driftmap.services import deletion, survey_layers
from driftmap.services import sites as site_service
from driftmap.store.models import SurveyLayerLevel, SurveyMap
from driftmap.store.storage import Storage


def noisy_plan() -> bytes:
    """A 1 km drift: two walls of 2,001 vertices with 5 cm noise (simplify well), a centreline, one LINE."""
    rng = np.random.default_rng(3)
    doc = new_dxf("R2000")
    msp = doc.modelspace()
    along = np.linspace(0.0, 1000.0, 2001)
    for offset in (-2.5, 2.5):
        across = offset + rng.normal(0.0, 0.05, along.size)
        msp.add_lwpolyline(
            list(zip(along.tolist(), across.tolist(), strict=True)), dxfattribs={"layer": "WALLS"}
        )
    msp.add_lwpolyline([(0.0, 0.0), (1000.0, 0.0)], dxfattribs={"layer": "CENTRELINE"})
    msp.add_line((0.0, -2.5), (0.0, 2.5), dxfattribs={"layer": "WALLS"})
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue().encode()


def _upload(storage: Storage, data: bytes) -> int:
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.get_site(session, "mine")
        return site_service.add_survey_map(session, batch, site, data, "plan.dxf").id


def _level_count(storage: Storage) -> int:
    with storage.db.session() as session:
        return session.scalar(select(func.count()).select_from(SurveyLayerLevel)) or 0


@pytest.fixture
def mine(storage: Storage) -> Storage:
    with storage.db.session() as session:
        site_service.create_site(session, "mine")
    return storage


class TestFirstLevels:
    def test_upload_stores_the_first_view_zooms(self, mine: Storage) -> None:
        survey_id = _upload(mine, noisy_plan())
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            rows = session.scalars(
                select(SurveyLayerLevel)
                .where(SurveyLayerLevel.survey_map_id == survey_id)
                .order_by(SurveyLayerLevel.zoom)
            ).all()
            assert [r.zoom for r in rows] == list(survey_layers.FIRST_VIEW_ZOOMS)
            for row in rows:
                assert row.tolerance_m == round(survey_layers.tolerance_for_zoom(survey, row.zoom), 6)
            walls = [r.vertices["WALLS"] for r in rows]
            assert walls[0] < 200 < 4004  # zoom 0 keeps a fraction of the walls' 2 x 2,001 + 2 vertices
            assert walls == sorted(walls)  # finer zooms keep more

    def test_a_fresh_process_is_served_from_the_store_without_loading_the_plan(self, mine: Storage) -> None:
        survey_id = _upload(mine, noisy_plan())
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            expected = survey_layers.survey_layers(
                survey, tolerance_m=survey_layers.tolerance_for_zoom(survey, 2)
            )
        survey_layers._cache.clear()  # as in another worker or after a restart
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            tolerance = survey_layers.tolerance_for_zoom(survey, 2)
            got = survey_layers.survey_layers(survey, tolerance_m=tolerance, session=session)
            assert "layers" not in inspect(survey).dict  # the plan's own (deferred) layers never loaded
            assert got == json.loads(json.dumps(expected))  # stored as JSON: tuples come back as lists
            # a zoom that was not stored is computed from the plan
            survey_layers.survey_layers(
                survey, tolerance_m=survey_layers.tolerance_for_zoom(survey, 9), session=session
            )
            assert "layers" in inspect(survey).dict

    def test_levels_nothing_simplifies_are_stored_once(self, mine: Storage) -> None:
        doc = new_dxf("R2000")
        for k in range(20):
            doc.modelspace().add_line((0.0, 10.0 * k), (500.0, 10.0 * k + 1.0), dxfattribs={"layer": "WALLS"})
        stream = io.StringIO()
        doc.write(stream)
        survey_id = _upload(mine, stream.getvalue().encode())
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            rows = session.scalars(
                select(SurveyLayerLevel)
                .where(SurveyLayerLevel.survey_map_id == survey_id)
                .order_by(SurveyLayerLevel.zoom)
            ).all()
            assert [(r.layers is None, r.same_as_zoom) for r in rows] == [(False, None)] + [(True, 0)] * 3
            expected = survey_layers.survey_layers(
                survey, tolerance_m=survey_layers.tolerance_for_zoom(survey, 3)
            )
        survey_layers._cache.clear()
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            tolerance = survey_layers.tolerance_for_zoom(survey, 3)
            got = survey_layers.survey_layers(survey, tolerance_m=tolerance, session=session)
            assert "layers" not in inspect(survey).dict
            assert got == json.loads(json.dumps(expected)) and got["vertices"] == 40

    def test_bad_input_and_rollback_leave_no_levels(self, mine: Storage) -> None:
        with pytest.raises(BadInputError):
            _upload(mine, b"0\nSECTION\n2\nENTITIES\n0\nNOT_A_DXF")
        assert _level_count(mine) == 0
        with pytest.raises(RuntimeError), mine.blobs.batch() as batch, mine.db.session() as session:
            site = site_service.get_site(session, "mine")
            site_service.add_survey_map(session, batch, site, noisy_plan(), "plan.dxf")
            raise RuntimeError("the request fails after the upload was added")
        with mine.db.session() as session:
            assert session.scalar(select(func.count()).select_from(SurveyMap)) == 0
        assert _level_count(mine) == 0

    def test_levels_go_with_their_site(self, mine: Storage) -> None:
        _upload(mine, noisy_plan())
        assert _level_count(mine) == len(survey_layers.FIRST_VIEW_ZOOMS)
        with mine.db.session() as session:
            deletion.delete_site(session, site_service.get_site(session, "mine"))
        assert _level_count(mine) == 0


def tiny_plan(width_m: float) -> bytes:
    """A plan ``width_m`` across: a wall, a label and a circle (its first-view tolerances are micrometres)."""
    doc = new_dxf("R2000")
    msp = doc.modelspace()
    msp.add_lwpolyline(
        [(0.0, 0.0), (width_m / 3, width_m / 50), (width_m, 0.0)], dxfattribs={"layer": "WALLS"}
    )
    msp.add_circle((width_m / 2, width_m / 4), width_m / 8, dxfattribs={"layer": "RING"})
    msp.add_text("DP", dxfattribs={"layer": "LABELS", "insert": (0.0, width_m / 2)})
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue().encode()


class TestToleranceKey:
    @pytest.mark.parametrize("width_m", [1e-9, 1e-6, 2e-3, 0.05, 1.0, 1000.0])
    def test_the_first_view_zooms_of_any_plan_have_distinct_positive_keys(self, width_m: float) -> None:
        survey = SurveyMap(min_x_m=0.0, min_y_m=0.0, max_x_m=width_m, max_y_m=0.0)
        keys = [
            survey_layers.tolerance_key(survey_layers.tolerance_for_zoom(survey, zoom))
            for zoom in survey_layers.FIRST_VIEW_ZOOMS
        ]
        assert len(set(keys)) == len(keys) and min(keys) > 0

    def test_tolerances_of_a_tenth_of_a_millimetre_and_more_round_to_micrometres(self) -> None:
        assert survey_layers.tolerance_key(1.23456789) == 1.234568
        assert survey_layers.tolerance_key(0.000123456) == 0.000123
        assert survey_layers.tolerance_key(1.23456e-7) == 1.23e-7
        assert survey_layers.tolerance_key(0.0) == 0.0


class TestTinyPlans:
    @pytest.mark.parametrize("width_m", [2e-3, 1e-5])
    def test_a_plan_millimetres_across_is_stored_and_served(self, mine: Storage, width_m: float) -> None:
        # such plans failed with IntegrityError: their zooms' tolerances all rounded to 0.0 micrometres
        survey_id = _upload(mine, tiny_plan(width_m))
        survey_layers._cache.clear()
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            rows = session.scalars(
                select(SurveyLayerLevel).where(SurveyLayerLevel.survey_map_id == survey_id)
            )
            assert len({row.tolerance_m for row in rows}) == len(survey_layers.FIRST_VIEW_ZOOMS)
            full = survey_layers.survey_layers(survey, session=session)
            stored = [f["geometry"] for layer in survey.layers.values() for f in layer["features"]]
            as_stored = sum(len(g["coordinates"]) if g["type"] == "LineString" else 1 for g in stored)
            assert full["vertices"] == as_stored  # tolerance 0 is the plan as stored, not a simplified level
        survey_layers._cache.clear()
        with mine.db.session() as session:
            survey = session.get_one(SurveyMap, survey_id)
            coarse = survey_layers.survey_layers(
                survey, tolerance_m=survey_layers.tolerance_for_zoom(survey, 0), session=session
            )
            assert "layers" not in inspect(survey).dict and set(coarse["layers"]) == {
                "LABELS",
                "RING",
                "WALLS",
            }

    def test_a_plan_of_one_point(self, mine: Storage) -> None:
        doc = new_dxf("R12")
        doc.modelspace().add_text("lonely", dxfattribs={"insert": (5.0, 5.0)})
        stream = io.StringIO()
        doc.write(stream)
        survey_id = _upload(mine, stream.getvalue().encode())
        with mine.db.session() as session:
            assert session.get_one(SurveyMap, survey_id).max_x_m == 5.0


class TestStoredSize:
    def test_a_plan_over_the_stored_size_is_refused_and_leaves_the_site_as_it_was(
        self, mine: Storage
    ) -> None:
        _upload(mine, tiny_plan(10.0))
        blobs_before = mine.blobs.all_names()
        with (
            pytest.raises(PayloadTooLargeError, match="survey_max_stored_bytes") as info,
            mine.blobs.batch() as batch,
            mine.db.session() as session,
        ):
            site = site_service.get_site(session, "mine")
            site_service.add_survey_map(
                session, batch, site, noisy_plan(), "big.dxf", DxfLimits(max_stored_bytes=100_000)
            )
        assert info.value.file == "big.dxf"
        assert mine.blobs.all_names() == blobs_before
        with mine.db.session() as session:
            assert session.scalar(select(func.count()).select_from(SurveyMap)) == 1
        assert _level_count(mine) == len(survey_layers.FIRST_VIEW_ZOOMS)

    def test_the_same_plan_within_the_limit_is_stored(self, mine: Storage) -> None:
        with mine.blobs.batch() as batch, mine.db.session() as session:
            site = site_service.get_site(session, "mine")
            record = site_service.add_survey_map(
                session, batch, site, noisy_plan(), "big.dxf", DxfLimits(max_stored_bytes=400_000)
            )
            assert record.id is not None
