"""Localisation against a stored map of the tiny simulated site, on a real SQLite file and blob store."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select

from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.params import IMAGES_DEFAULT
from driftmap.core.imaging.views import thumbnails
from driftmap.errors import BadInputError, NotFoundError
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder
from driftmap.formats.drive_json import lens_to_json
from driftmap.formats.frame_images import decode_gray
from driftmap.services import localisation as loc_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.models import Drive, Frame, MapNodeFrame, MapVersion
from driftmap.store.storage import Storage
from tests.core.imaging.boards import FISHEYE
from tests.core.localisation.test_localiser_lens import CAMERA, corridor, lens_frames
from tests.localisation_site import SITE, loc_drive_dir, tiny_map_settings

ON_NODE_M = 15.0  # a frame is localised right when its node centre is within this of the truth, metres
MIN_RIGHT = 0.9  # fraction of matched frames of the tiny site's localisation drive that must be right
MIN_MATCHED = 0.5  # fraction of its frames the HMM must mark matched


@pytest.fixture(scope="module")
def tiny_store(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path) -> Iterator[Storage]:
    storage = Storage.open(tiny_map_settings(tmp_path_factory, tiny_site_dir))
    yield storage
    storage.close()


class TestMakeLocaliser:
    def test_the_camera_lens_applies_without_odometry(self) -> None:
        frames = lens_frames()
        lmap = corridor(thumbnails(frames, IMAGES_DEFAULT, FISHEYE))
        loc = loc_service.make_localiser(lmap, sesame=None, temporal=False, camera=CAMERA, odometry=False)
        assert loc.odometry is None and loc.lens == FISHEYE
        assert loc.step(frames[3], 0.0).node == 3


class TestLoadLocaliserMap:
    def test_database_blob_matches_the_map(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            site = site_service.get_site(session, SITE)
            version = map_service.get_map_version(session, site)
            assert isinstance(version.stats.get(map_service.LOCALISER_DB_KEY), str)
            lmap = loc_service.load_localiser_map(session, tiny_store.blobs, site)
            topomap = map_service.load_topomap(tiny_store.blobs, version)
        assert lmap.n_nodes == topomap.n_nodes
        assert np.array_equal(lmap.node_ptr, topomap.chosen_ptr)
        assert lmap.thumbs.shape == (topomap.chosen.size, 32, 64)
        assert np.allclose(lmap.centres_m, topomap.centres_m)
        assert version.stats["reference_frames"] == topomap.chosen.size

    def test_mapped_paths_run_through_the_reference_positions(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            lmap = loc_service.load_localiser_map(
                session, tiny_store.blobs, site_service.get_site(session, SITE)
            )
        assert lmap.path_xy_m is not None and lmap.ref_xy_m is not None
        ends = lmap.path_xy_m[lmap.path_segments]
        lengths = np.hypot(*(ends[:, 1] - ends[:, 0]).T)
        assert lmap.path_segments.shape[0] > 0.9 * lmap.path_xy_m.shape[0]  # a few drives: a few chains
        assert lengths.min() >= 1.0 and lengths.max() <= 10.0
        for ref in lmap.ref_xy_m:  # every reference frame lies on a mapped path (within a vertex's step)
            assert np.min(np.hypot(*(lmap.path_xy_m - ref).T)) <= 1.0

    def test_without_blob_thumbnails_are_made_from_the_node_frames(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            site = site_service.get_site(session, SITE)
            version = map_service.get_map_version(session, site)
            stored = loc_service.load_version_localiser_map(session, tiny_store.blobs, version)
            session.expunge(version)
            bare = MapVersion(
                id=version.id,
                version=version.version,
                params=version.params,
                stats={},
                topomap_sha256=version.topomap_sha256,
            )
            rebuilt = loc_service.load_version_localiser_map(session, tiny_store.blobs, bare)
        assert np.array_equal(rebuilt.node_ptr, stored.node_ptr)
        assert np.abs(rebuilt.thumbs - stored.thumbs).max() < 0.01  # the blob holds float16

    def test_references_made_from_frames_take_their_drive_camera_view(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            site = site_service.get_site(session, SITE)
            version = map_service.get_map_version(session, site)
            bare = MapVersion(id=version.id, version=version.version, params=version.params, stats={})
            bare.topomap_sha256 = version.topomap_sha256
            drives = session.scalars(select(Drive).where(Drive.site_id == site.id)).all()
            width, height = drives[0].camera["width"], drives[0].camera["height"]
            f = width / 3.0  # a 170-degree fisheye across the width
            lens = Lens("fisheye", ((f, 0.0, width / 2), (0.0, f, height / 2), (0.0, 0.0, 1.0)), (0.0,) * 4)
            for drive in drives:  # not committed: rolled back below
                drive.camera = {**drive.camera, "lens": lens_to_json(lens)}
            session.flush()
            first_sha = session.scalars(
                select(Frame.blob_sha256)
                .join(MapNodeFrame, MapNodeFrame.frame_id == Frame.id)
                .where(MapNodeFrame.map_version_id == version.id)
                .order_by(MapNodeFrame.node, MapNodeFrame.rank)
            ).first()
            assert first_sha is not None
            frame = decode_gray(tiny_store.blobs.get(first_sha), "first reference")
            rebuilt = loc_service.load_version_localiser_map(session, tiny_store.blobs, bare)
            params = loc_service.image_params_of(version)
            session.rollback()
        np.testing.assert_array_equal(rebuilt.thumbs[0], thumbnails(frame, params, lens))
        assert not np.array_equal(rebuilt.thumbs[0], thumbnails(frame, params, None))

    def test_no_map_version(self, storage: Storage, tiny_site_dir: Path) -> None:
        with storage.db.session() as session:
            site = site_service.create_site(session, "empty")
            with pytest.raises(NotFoundError, match="map build"):
                loc_service.load_localiser_map(session, storage.blobs, site)

    def test_map_parameters_round_trip(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            version = map_service.get_map_version(session, site_service.get_site(session, SITE))
            assert loc_service.image_params_of(version).size_px == (64, 32)
            assert loc_service.sesame_params_of(version).patch_sizes_px == (5, 10, 20)


class TestLocaliseFrames:
    def test_recorded_drive_lands_on_its_true_places(self, tiny_store: Storage, tiny_site_dir: Path) -> None:
        with tiny_store.db.session() as session:
            lmap = loc_service.load_localiser_map(
                session, tiny_store.blobs, site_service.get_site(session, SITE)
            )
        folder = read_drive_folder(loc_drive_dir(tiny_site_dir))
        frames = [decode_gray(data, "frame") for _row, data in iter_frame_images(folder)]
        seen: list[tuple[str, float]] = []
        estimates = loc_service.localise_frames(
            loc_service.make_localiser(lmap),
            frames,
            [f.t_s for f in folder.frames],
            lambda s, f: seen.append((s, f)),
        )
        assert len(estimates) == len(frames) and seen[-1] == ("localise", 1.0)
        truth = np.array([[f.x_m, f.y_m] for f in folder.frames], dtype=np.float64)
        est = np.array([[e.x_m, e.y_m] for e in estimates])
        matched = np.array([e.matched for e in estimates])
        assert matched.mean() >= MIN_MATCHED
        right = np.linalg.norm(est - truth, axis=1) <= ON_NODE_M
        assert right[matched].mean() >= MIN_RIGHT
        rows = loc_service.estimate_rows([f.frame for f in folder.frames], estimates)
        assert [r.frame for r in rows] == [f.frame for f in folder.frames]
        assert [r.matched for r in rows] == matched.tolist()

    def test_stored_localisation_drives_carry_truth(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            site = site_service.get_site(session, SITE)
            drives = loc_service.load_localisation_drives(session, tiny_store.blobs, site)
        assert [d.name for d in drives] == ["loc-01"]
        drive = drives[0]
        assert drive.truth_xy_m is not None and drive.truth_xy_m.shape == (drive.t_s.size, 2)
        first = next(iter(drive.frames()))
        assert first.dtype == np.uint8 and first.ndim == 2

    def test_frame_count_must_match_times(self, tiny_store: Storage) -> None:
        with tiny_store.db.session() as session:
            lmap = loc_service.load_localiser_map(
                session, tiny_store.blobs, site_service.get_site(session, SITE)
            )
        frame = np.zeros((240, 320), dtype=np.uint8)
        with pytest.raises(BadInputError, match="timestamps"):
            loc_service.localise_frames(loc_service.make_localiser(lmap), [frame, frame], [0.0])
