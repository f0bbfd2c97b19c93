"""Groundings as survey control on a real database: station and enabled, the site control file in and out
(each bad row named, nothing half-written), and builds that leave disabled groundings out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.mapping.pipeline import MAPPING_FAST
from driftmap.errors import BadInputError, ConflictError
from driftmap.formats.control_csv import parse_control_rows
from driftmap.services import groundings as grounding_service
from driftmap.services import maps as map_service
from driftmap.services import residuals as residual_service
from driftmap.services import sites as site_service
from driftmap.services.map_drives import load_mapping_drive, mapping_drives
from driftmap.store.models import Drive, Grounding, MapPose, MapVersion
from driftmap.store.storage import Storage
from tests.jobs.mini_site import MINI_FRAMES
from tests.sim_site import import_site


@pytest.fixture
def mini(storage: Storage, mini_site: Path) -> Storage:
    """The mini site (one grounding on each mapping drive) imported as site ``tiny``."""
    import_site(storage, mini_site, name="tiny", kinds=("mapping", "localisation"))
    return storage


def _site_id(storage: Storage) -> int:
    with storage.db.session() as session:
        return site_service.get_site(session, "tiny").id


def _build_mini(storage: Storage) -> None:
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.get_site(session, "tiny")
        map_service.build_site_map(session, storage.blobs, batch, site, MAPPING_FAST)


def _poses(session: Session, version: MapVersion) -> np.ndarray:
    """The (N, 2) map poses of ``version``, metres, in frame order."""
    rows = session.execute(
        select(MapPose.x_m, MapPose.y_m)
        .where(MapPose.map_version_id == version.id)
        .order_by(MapPose.frame_id)
    )
    return np.array([tuple(r) for r in rows], dtype=float)


def _export(storage: Storage) -> str:
    with storage.db.session() as session:
        return grounding_service.export_site_csv(session, _site_id(storage))


class TestEnabled:
    def test_disabled_groundings_stay_out_of_builds(self, mini: Storage) -> None:
        with mini.db.session() as session:
            marks = list(session.scalars(select(Grounding).order_by(Grounding.id)))
            grounding_service.update_grounding(session, marks[0], enabled=False, station="STN-104")
        with mini.db.session() as session:
            site = site_service.get_site(session, "tiny")
            loaded = [load_mapping_drive(session, mini.blobs, d) for d in mapping_drives(session, site)]
            used = [gid for one in loaded for gid in one.grounding_ids]
            assert marks[0].id not in used and set(used) == {m.id for m in marks[1:]}
            map_service.ensure_buildable(session, site)
            stored = session.get(Grounding, marks[0].id)
            assert stored is not None and (stored.enabled, stored.station) == (False, "STN-104")
        with mini.db.session() as session:
            for mark in session.scalars(select(Grounding)):
                grounding_service.update_grounding(session, mark, enabled=False)
        with (
            mini.db.session() as session,
            pytest.raises(ConflictError, match="no grounding on any mapping drive that is enabled"),
        ):
            map_service.ensure_buildable(session, site_service.get_site(session, "tiny"))

    def test_station_is_cleaned_and_cleared(self, mini: Storage) -> None:
        with mini.db.session() as session:
            mark = session.scalars(select(Grounding)).first()
            assert mark is not None
            grounding_service.update_grounding(session, mark, station="  STN-7 ")
            assert mark.station == "STN-7"
            grounding_service.update_grounding(session, mark, station="")
            assert mark.station is None
            with pytest.raises(BadInputError) as caught:
                grounding_service.update_grounding(session, mark, station="S" * 65)
            assert caught.value.field == "station"


class TestSiteControlFile:
    def test_export_import_round_trip(self, mini: Storage) -> None:
        original = _export(mini)
        rows = [r for _line, r in parse_control_rows(original, "c")]
        assert len(rows) == 2 and all(r.enabled and r.station is None for r in rows)
        first = rows[0]
        edited = (
            "drive,frame,station,x,y,enabled\n"
            f"{first.drive},{first.frame},STN-1,{first.x_m!r},{first.y_m!r},true\n"
            f"{first.drive},{first.frame + 5},,1.5,-2.5,false\n"
        )
        with mini.db.session() as session:
            assert (
                grounding_service.import_site_csv(session, _site_id(mini), edited.encode(), "c.csv", "t") == 2
            )
        assert _export(mini) == edited
        with mini.db.session() as session:
            grounding_service.import_site_csv(session, _site_id(mini), original.encode(), "c.csv", "t")
        assert _export(mini) == original

    def test_a_point_switched_off_in_the_file_changes_the_build(self, mini: Storage) -> None:
        """A control point about 85 m off its drive pulls the map while enabled; switched off in the file (and
        the file read back), the next build leaves it out."""
        header, *rows = _export(mini).splitlines()
        drive, frame, _station, x, y, _enabled = rows[0].split(",")
        other = (int(frame) + 50) % MINI_FRAMES
        far = f"{drive},{other},STN-FAR,{float(x) + 60.0!r},{float(y) + 60.0!r},"
        for enabled in ("true", "false"):
            text = "\n".join([header, *rows, far + enabled]) + "\n"
            with mini.db.session() as session:
                grounding_service.import_site_csv(session, _site_id(mini), text.encode(), "c.csv", "t")
            assert sorted(_export(mini).splitlines()) == sorted(text.splitlines())  # in drive, frame order
            _build_mini(mini)
        with mini.db.session() as session:
            versions = list(session.scalars(select(MapVersion).order_by(MapVersion.version)))
            pulled, kept = (residual_service.residual_rows(session, v) for v in versions)
            moved = [_poses(session, v) for v in versions]
        assert len(pulled) == 3 and len(kept) == 2  # the residuals of the enabled points only
        assert max(r.distance_m for r in pulled) > 5.0 and max(r.distance_m for r in kept) < 2.0
        assert np.abs(moved[0] - moved[1]).max() > 5.0  # the far point moved the map

    def test_each_bad_row_is_named_and_nothing_changes(self, mini: Storage) -> None:
        before = _export(mini)
        with mini.db.session() as session:
            localisation = session.scalar(select(Drive.name).where(Drive.kind == "localisation"))
            mapping = session.scalar(select(Drive.name).where(Drive.kind == "mapping"))
        good = f"{mapping},1,,0.0,0.0,true\n"
        cases = [
            ("nowhere,1,,0,0,true", "drive"),
            (f"{localisation},1,,0,0,true", "drive"),
            (f"{mapping},100000,,0,0,true", "frame"),
            (f"{mapping},2,,1e999,0,true", "x"),
            (f"{mapping},1,,0,0,true", "frame"),
            (f"{mapping},2,,0,0,perhaps", "enabled"),
        ]
        for row, field in cases:
            text = "drive,frame,station,x,y,enabled\n" + good + row + "\n"
            with mini.db.session() as session, pytest.raises(BadInputError) as caught:
                grounding_service.import_site_csv(session, _site_id(mini), text.encode(), "c.csv", "t")
            assert (caught.value.file, caught.value.line, caught.value.field) == ("c.csv", 3, field), row
        assert _export(mini) == before
