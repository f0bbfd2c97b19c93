"""Tests of driftmap.formats.video: video files made with cv2.VideoWriter inside the tests."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from driftmap.errors import BadInputError
from driftmap.formats.drive_json import camera_to_json
from driftmap.formats.frame_images import check_frame_image
from driftmap.formats.video import read_calibration_json, read_video_drive
from tests.formats.builders import HEIGHT_PX, WIDTH_PX, make_camera

FPS = 5.0
TIME_TOL_S = 1e-3  # decoder timestamps are in milliseconds


def write_video(
    path: Path,
    frames: int = 6,
    *,
    fourcc: str = "MJPG",
    size: tuple[int, int] = (WIDTH_PX, HEIGHT_PX),
    grey: bool,
) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*fourcc), FPS, size)
    if not writer.isOpened():
        pytest.skip(f"codec {fourcc} not available in this OpenCV build")
    rng = np.random.default_rng(0)
    for i in range(frames):
        if grey:
            level = np.full((size[1], size[0]), 20 * i + 30, np.uint8)
            writer.write(cv2.cvtColor(level, cv2.COLOR_GRAY2BGR))
        else:
            writer.write(rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8))
    writer.release()
    return path


def write_calibration(path: Path, *, wrapped: bool = False, fps: float | str | None = None) -> Path:
    block = camera_to_json(make_camera())
    obj: dict[str, object] = {"camera": block} if wrapped else dict(block)
    if fps is not None:
        obj["fps"] = fps
    path.write_text(json.dumps(obj, indent=2))
    return path


def line_of(path: Path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().split("\n"), start=1) if needle in line)


class TestReadVideo:
    @pytest.mark.parametrize(("suffix", "fourcc"), [(".avi", "MJPG"), (".mp4", "mp4v")])
    def test_frames_times_and_meta(self, tmp_path: Path, suffix: str, fourcc: str) -> None:
        video = write_video(tmp_path / f"clip{suffix}", fourcc=fourcc, grey=False)
        meta, rows, images = read_video_drive(
            video, write_calibration(tmp_path / "c.json"), name="clip", kind="mapping"
        )
        assert (meta.name, meta.kind, meta.fps, meta.camera) == ("clip", "mapping", FPS, make_camera())
        assert [r.frame for r in rows] == list(range(6))
        assert [r.t_s for r in rows] == pytest.approx([i / FPS for i in range(6)], abs=TIME_TOL_S)
        assert not any(r.has_truth for r in rows)
        pngs = list(images)
        assert len(pngs) == 6
        for png in pngs:
            assert check_frame_image(png, "f", WIDTH_PX, HEIGHT_PX).shape == (HEIGHT_PX, WIDTH_PX, 3)

    def test_grey_video_gives_grey_frames(self, tmp_path: Path) -> None:
        video = write_video(tmp_path / "grey.avi", grey=True)
        _, _, images = read_video_drive(
            video, write_calibration(tmp_path / "c.json"), name="g", kind="localisation"
        )
        decoded = [check_frame_image(png, "f", WIDTH_PX, HEIGHT_PX) for png in images]
        assert all(d.ndim == 2 for d in decoded)
        assert [int(d.mean()) for d in decoded] == pytest.approx([20 * i + 30 for i in range(6)], abs=3)

    def test_fps_override_sets_times(self, tmp_path: Path) -> None:
        video = write_video(tmp_path / "clip.avi", grey=True)
        calibration = write_calibration(tmp_path / "c.json", wrapped=True, fps=20.0)
        meta, rows, _ = read_video_drive(video, calibration, name="clip", kind="mapping")
        assert meta.fps == 20.0
        assert [r.t_s for r in rows] == [i / 20.0 for i in range(6)]


class TestVideoErrors:
    def test_missing_video(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match="missing"):
            read_video_drive(
                tmp_path / "no.avi", write_calibration(tmp_path / "c.json"), name="n", kind="mapping"
            )

    def test_unreadable_video(self, tmp_path: Path) -> None:
        video = tmp_path / "bad.avi"
        video.write_bytes(b"RIFF but not really a video" * 10)
        with pytest.raises(BadInputError) as info:
            read_video_drive(video, write_calibration(tmp_path / "c.json"), name="n", kind="mapping")
        assert info.value.file == str(video)

    def test_zero_frames(self, tmp_path: Path) -> None:
        video = write_video(tmp_path / "empty.avi", frames=0, grey=True)
        with pytest.raises(BadInputError) as info:
            read_video_drive(video, write_calibration(tmp_path / "c.json"), name="n", kind="mapping")
        assert info.value.file == str(video)

    def test_size_disagreeing_with_calibration(self, tmp_path: Path) -> None:
        video = write_video(tmp_path / "big.avi", size=(WIDTH_PX * 2, HEIGHT_PX), grey=True)
        with pytest.raises(BadInputError) as info:
            read_video_drive(video, write_calibration(tmp_path / "c.json"), name="n", kind="mapping")
        assert (
            f"{WIDTH_PX * 2}x{HEIGHT_PX}" in info.value.reason
            and f"{WIDTH_PX}x{HEIGHT_PX}" in info.value.reason
        )

    def test_bad_kind(self, tmp_path: Path) -> None:
        video = write_video(tmp_path / "clip.avi", grey=True)
        with pytest.raises(BadInputError) as info:
            read_video_drive(video, write_calibration(tmp_path / "c.json"), name="n", kind="survey")
        assert info.value.field == "kind"


class TestCalibration:
    @pytest.mark.parametrize("wrapped", [False, True])
    def test_flat_or_wrapped_camera_block(self, tmp_path: Path, wrapped: bool) -> None:
        camera, fps = read_calibration_json(write_calibration(tmp_path / "c.json", wrapped=wrapped))
        assert (camera, fps) == (make_camera(), None)

    def test_bad_fps(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError) as info:
            read_calibration_json(write_calibration(tmp_path / "c.json", fps="fast"))
        assert (info.value.field, info.value.line) == ("fps", line_of(tmp_path / "c.json", '"fps"'))

    @pytest.mark.parametrize("wrapped", [False, True])
    def test_bad_camera_key_names_file_line_and_key(self, tmp_path: Path, wrapped: bool) -> None:
        path = write_calibration(tmp_path / "c.json", wrapped=wrapped)
        path.write_text(path.read_text().replace('"k_y": 0.3333333333333333', '"k_y": "1/3"'))
        with pytest.raises(BadInputError) as info:
            read_calibration_json(path)
        expected = (str(path), line_of(path, '"k_y"'), "camera.k_y")
        assert (info.value.file, info.value.line, info.value.field) == expected

    def test_missing_file(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match="missing"):
            read_calibration_json(tmp_path / "nothing.json")
