"""Drive import, export and listing against a real SQLite file and blob store."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from sqlalchemy import func, select

from driftmap.errors import BadInputError, ConflictError
from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.store.models import Drive, Frame, Grounding, Site
from driftmap.store.storage import Storage
from tests.drive_factory import CAMERA, write_test_drive


def _site(storage: Storage, name: str = "mine") -> None:
    with storage.db.session() as session:
        site_service.create_site(session, name)


def _import(storage: Storage, path: Path, site_name: str = "mine", **video: str | None) -> None:
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.get_site(session, site_name)
        drive_service.import_drive(session, batch, site, path, **video)  # type: ignore[arg-type]


def _counts(storage: Storage) -> tuple[int, int, int, int]:
    with storage.db.session() as session:
        drives = session.scalar(select(func.count()).select_from(Drive)) or 0
        frames = session.scalar(select(func.count()).select_from(Frame)) or 0
        groundings = session.scalar(select(func.count()).select_from(Grounding)) or 0
    return drives, frames, groundings, len(storage.blobs.all_names())


class TestImport:
    def test_rows_blobs_and_groundings(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        _import(storage, write_test_drive(tmp_path / "d", frames=12))
        assert _counts(storage) == (1, 12, 2, 12)
        with storage.db.session() as session:
            drive = session.scalars(select(Drive)).one()
            frames = drive_service.frame_rows(session, drive)
            assert [f.index for f in frames] == list(range(12))
            assert frames[3].t_s == pytest.approx(0.3)
            assert frames[3].true_x_m == pytest.approx(12000.0 + 0.37 * 3)
            assert (
                storage.blobs.get(frames[3].blob_sha256)
                == (tmp_path / "d" / "frames" / "000003.png").read_bytes()
            )
            assert drive.camera["ground_roi"] == [16, 24, 32, 20]

    def test_duplicate_name_is_a_conflict_and_writes_nothing(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        _import(storage, write_test_drive(tmp_path / "a", seed=1))
        before = _counts(storage)
        with pytest.raises(ConflictError, match="east-mapping-1"):
            _import(storage, write_test_drive(tmp_path / "b", seed=2))
        assert _counts(storage) == before

    def test_truncated_frame_leaves_no_rows_and_no_orphan_blobs(
        self, storage: Storage, tmp_path: Path
    ) -> None:
        _site(storage)
        _import(storage, write_test_drive(tmp_path / "ok", name="kept", seed=5))
        before = _counts(storage)
        bad = write_test_drive(tmp_path / "bad", name="broken", seed=6, frames=20)
        victim = bad / "frames" / "000015.png"
        victim.write_bytes(victim.read_bytes()[: len(victim.read_bytes()) // 2])
        with pytest.raises(BadInputError, match=r"000015\.png"):
            _import(storage, bad)
        assert _counts(storage) == before

    def test_frame_of_other_size_names_the_file(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        bad = write_test_drive(tmp_path / "bad", frames=6)
        _, data = cv2.imencode(".png", np.zeros((10, 10), np.uint8))
        (bad / "frames" / "000004.png").write_bytes(data.tobytes())
        with pytest.raises(BadInputError, match=r"000004\.png"):
            _import(storage, bad)
        assert _counts(storage) == (0, 0, 0, 0)

    def test_grounding_of_absent_frame_is_rejected(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        bad = write_test_drive(tmp_path / "bad", frames=6)
        (bad / "groundings.csv").write_text("frame,x,y\n0,1.0,2.0\n99,3.0,4.0\n")
        with pytest.raises(BadInputError, match=r"groundings.csv:3"):
            _import(storage, bad)
        assert _counts(storage) == (0, 0, 0, 0)

    def test_video_with_calibration(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        video = tmp_path / "clip.avi"
        writer = cv2.VideoWriter(
            str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, (CAMERA.width_px, CAMERA.height_px)
        )
        rng = np.random.default_rng(3)
        for _ in range(8):
            writer.write(rng.integers(0, 256, (CAMERA.height_px, CAMERA.width_px, 3), dtype=np.uint8))
        writer.release()
        calibration = tmp_path / "camera.json"
        camera = json.loads((write_test_drive(tmp_path / "ref") / "drive.json").read_text())["camera"]
        calibration.write_text(json.dumps(camera))
        _import(storage, video, calibration=str(calibration), name="clip", kind="localisation")
        with storage.db.session() as session:
            drive = session.scalars(select(Drive)).one()
            assert (drive.name, drive.kind, drive.frame_count) == ("clip", "localisation", 8)
            times = [f.t_s for f in drive_service.frame_rows(session, drive)]
        assert times == pytest.approx([i / 5.0 for i in range(8)], abs=1e-3)

    def test_video_without_calibration_is_rejected(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        video = tmp_path / "clip.avi"
        video.write_bytes(b"not really a video")
        with pytest.raises(BadInputError, match="calibration"):
            _import(storage, video)


class TestExport:
    def test_import_export_import_gives_identical_data(self, storage: Storage, tmp_path: Path) -> None:
        source = write_test_drive(tmp_path / "src", frames=15, seed=9)
        _site(storage, "first")
        _site(storage, "second")
        _import(storage, source, "first")
        out = tmp_path / "exported"
        with storage.db.session() as session:
            drive_service.export_drive(
                session, storage.blobs, site_service.get_site(session, "first"), "east-mapping-1", out
            )
        for name in ("drive.json", "frames.csv", "groundings.csv"):
            assert (out / name).read_bytes() == (source / name).read_bytes(), name
        _import(storage, out, "second")

        def snapshot(site_name: str) -> tuple[object, ...]:
            with storage.db.session() as session:
                site = session.scalars(select(Site).where(Site.name == site_name)).one()
                drive = drive_service.get_drive(session, site, "east-mapping-1")
                frames = [
                    (f.index, f.t_s, f.blob_sha256, f.image_ext, f.true_x_m, f.true_y_m, f.true_yaw_rad)
                    for f in drive_service.frame_rows(session, drive)
                ]
                marks = drive_service.grounding_rows(session, drive)
                return (drive.kind, drive.fps, drive.camera, frames, marks)

        assert snapshot("first") == snapshot("second")

    def test_list_summarises_each_drive(self, storage: Storage, tmp_path: Path) -> None:
        _site(storage)
        _import(storage, write_test_drive(tmp_path / "a", name="a", frames=11))
        _import(storage, write_test_drive(tmp_path / "b", name="b", frames=5, groundings=False, truth=False))
        with storage.db.session() as session:
            rows = drive_service.list_drives(session, site_service.get_site(session, "mine"))
        assert [(r.name, r.frame_count, r.grounding_count, r.has_truth) for r in rows] == [
            ("a", 11, 2, True),
            ("b", 5, 0, False),
        ]
        assert rows[0].duration_s == pytest.approx(1.0)
