"""Map builds on a simulated site against a real SQLite file: versions, poses, residuals, nodes."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import delete, func, select

from driftmap.core.mapping.pipeline import MAPPING_FAST
from driftmap.errors import ConflictError, NotFoundError
from driftmap.formats.csv_exports import read_poses_csv, write_poses_csv
from driftmap.services import maps as map_service
from driftmap.services import residuals as residual_service
from driftmap.services import sites as site_service
from driftmap.store.models import Drive, Frame, Grounding, MapNode, MapNodeFrame, MapPose, MapVersion
from driftmap.store.storage import Storage
from tests.sim_site import create_site, import_folders, import_site, version_poses

MAP_ERROR_TOLERANCE_M = 3.0  # mean distance to truth of the tiny site's optimised map, metres


def _build(storage: Storage) -> int:
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.get_site(session, "tiny")
        version, _build = map_service.build_site_map(session, storage.blobs, batch, site, MAPPING_FAST)
        return version.id


@pytest.mark.slow
class TestBuild:
    def test_version_holds_poses_residuals_and_nodes(
        self, storage: Storage, tiny_site_dir: Path, tmp_path: Path
    ) -> None:
        import_site(storage, tiny_site_dir)
        vid = _build(storage)
        with storage.db.session() as session:
            version = session.get(MapVersion, vid)
            assert version is not None and version.version == 1
            frames = session.scalar(select(func.count()).select_from(Frame)) or 0
            poses = session.scalar(
                select(func.count()).select_from(MapPose).where(MapPose.map_version_id == vid)
            )
            assert poses == frames
            marks = session.scalar(select(func.count()).select_from(Grounding))
            residuals = residual_service.residual_rows(session, version)
            assert len(residuals) == marks
            assert max(r.distance_m for r in residuals) < 2.0
            nodes = (
                session.scalar(select(func.count()).select_from(MapNode).where(MapNode.map_version_id == vid))
                or 0
            )
            assert nodes >= 10
            chosen = session.scalars(
                select(MapNodeFrame.node).where(MapNodeFrame.map_version_id == vid)
            ).all()
            assert set(chosen) <= set(range(nodes))
            topomap = map_service.load_topomap(storage.blobs, version)
            assert topomap.n_nodes == nodes

            rows = map_service.pose_rows(session, version)
            truth = {
                (name, i): (x, y)
                for name, i, x, y in session.execute(
                    select(Drive.name, Frame.index, Frame.true_x_m, Frame.true_y_m).join(Drive)
                ).all()
            }
        assert len(rows) == frames
        errors = np.array(
            [np.hypot(r.x_m - x, r.y_m - y) for r, (x, y) in zip(rows, truth.values(), strict=True)]
        )
        assert errors.mean() < MAP_ERROR_TOLERANCE_M
        out = tmp_path / "poses.csv"
        write_poses_csv(out, rows)
        assert read_poses_csv(out) == rows

    def test_versions_are_immutable_and_count_up(self, storage: Storage, tiny_site_dir: Path) -> None:
        import_site(storage, tiny_site_dir)
        first = _build(storage)
        with storage.db.session() as session:
            before = [
                (p.frame_id, p.x_m, p.y_m)
                for p in session.scalars(select(MapPose).where(MapPose.map_version_id == first))
            ]
            mark = session.scalars(select(Grounding).order_by(Grounding.id)).first()
            assert mark is not None
            mark.x_m += 3.0
        second = _build(storage)
        with storage.db.session() as session:
            after = [
                (p.frame_id, p.x_m, p.y_m)
                for p in session.scalars(select(MapPose).where(MapPose.map_version_id == first))
            ]
            site = site_service.get_site(session, "tiny")
            assert map_service.get_map_version(session, site).id == second
            assert map_service.get_map_version(session, site, 1).id == first
            with pytest.raises(NotFoundError, match="version 7"):
                map_service.get_map_version(session, site, 7)
        assert before == after


class TestWorkerProcesses:
    def test_drives_prepared_in_worker_processes_give_the_same_version(
        self, storage: Storage, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        versions = []
        for workers in (1, 2):  # 2: two spawned processes open the same SQLite file and blob store
            with storage.blobs.batch() as batch, storage.db.session() as session:
                site = site_service.get_site(session, "tiny")
                version, build = map_service.build_site_map(  # full: the second prepares every drive again
                    session, storage.blobs, batch, site, MAPPING_FAST, workers=workers, full=True
                )
                versions.append((version.id, build))
        with storage.db.session() as session:
            poses = [
                session.execute(
                    select(MapPose.frame_id, MapPose.x_m, MapPose.y_m, MapPose.yaw_rad)
                    .where(MapPose.map_version_id == vid)
                    .order_by(MapPose.frame_id)
                ).all()
                for vid, _build in versions
            ]
        assert len(poses[0]) == 200 and poses[0] == poses[1]
        (_a, one), (_b, two) = versions
        assert [c.d_score for c in one.closures] == [c.d_score for c in two.closures]
        assert np.array_equal(one.topomap.centres_m, two.topomap.centres_m)

    def test_kept_drives_joined_while_workers_prepare_a_new_one_give_the_full_build(
        self, storage: Storage, tiny_site_dir: Path
    ) -> None:
        params = dataclasses.replace(MAPPING_FAST, segment_frames=128)  # the new drive: 3 segments
        folders = [tiny_site_dir / "drives" / name for name in ("map-01", "map-02")]
        create_site(storage, tiny_site_dir, "tiny")
        versions = []
        for imported, workers, full in ((folders[:1], 1, False), (folders[1:], 2, False), ([], 1, True)):
            import_folders(storage, "tiny", imported)
            with storage.blobs.batch() as batch, storage.db.session() as session:
                site = site_service.get_site(session, "tiny")
                version, build = map_service.build_site_map(
                    session, storage.blobs, batch, site, params, workers=workers, full=full
                )
                versions.append((version.id, build.stats))
        (_v1, _first), (grown_id, grown), (full_id, rebuilt) = versions
        assert (grown["segments_reused"], grown["segments_prepared"]) == (6, 3)
        assert rebuilt["segments_reused"] == 0
        np.testing.assert_array_equal(version_poses(storage, grown_id), version_poses(storage, full_id))


class TestRefusals:
    def test_site_without_groundings_is_not_buildable(self, storage: Storage, tiny_site_dir: Path) -> None:
        import_site(storage, tiny_site_dir)
        with storage.db.session() as session:
            session.execute(delete(Grounding))
        with storage.db.session() as session, pytest.raises(ConflictError, match="no grounding"):
            map_service.ensure_buildable(session, site_service.get_site(session, "tiny"))

    def test_site_without_mapping_drives(self, storage: Storage) -> None:
        with storage.db.session() as session:
            site = site_service.create_site(session, "empty")
            with pytest.raises(NotFoundError, match="no mapping drive"):
                map_service.load_site_drives(session, storage.blobs, site)
