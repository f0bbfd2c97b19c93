"""Tests of driftmap.formats.camera_setup and the lens in drive.json (driftmap-drive/2)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.lens import Lens
from driftmap.errors import BadInputError
from driftmap.formats.camera_setup import (
    calibration_images,
    complete_camera,
    read_camera_file,
    read_ground_points,
    write_camera_file,
)
from driftmap.formats.drive_json import camera_to_json, dump_drive_json, parse_camera_block, parse_drive_json
from tests.formats.builders import make_camera, make_meta

LENS = Lens("fisheye", ((20.0, 0.0, 16.5), (0.0, 19.5, 12.25), (0.0, 0.0, 1.0)), (0.1, -0.01, 1e-3, 1 / 3))
V1_TEXT = dump_drive_json(make_meta(homography=True))


class TestDriveJsonVersions:
    def test_v1_without_lens_is_written_unchanged(self) -> None:
        meta = parse_drive_json(V1_TEXT, "drive.json")
        assert meta.camera.lens is None
        assert json.loads(V1_TEXT)["format"] == "driftmap-drive/1"
        assert dump_drive_json(meta) == V1_TEXT

    @pytest.mark.parametrize("model", ["pinhole", "fisheye"])
    def test_v2_with_lens_round_trips(self, model: str) -> None:
        dist = (0.1, -0.2, 1e-3, -1e-3, 0.05) if model == "pinhole" else LENS.distortion
        lens = Lens(model, LENS.K, dist)  # type: ignore[arg-type]
        meta = dataclasses.replace(make_meta(), camera=dataclasses.replace(make_camera(), lens=lens))
        text = dump_drive_json(meta)
        assert json.loads(text)["format"] == "driftmap-drive/2"
        assert json.loads(text)["camera"]["lens"] == {
            "model": model,
            "K": [list(r) for r in LENS.K],
            "distortion": list(dist),
        }
        assert parse_drive_json(text, "drive.json") == meta

    def test_v1_with_a_lens_is_refused(self) -> None:
        obj = json.loads(V1_TEXT)
        obj["camera"]["lens"] = {
            "model": "fisheye",
            "K": [list(r) for r in LENS.K],
            "distortion": [0, 0, 0, 0],
        }
        with pytest.raises(BadInputError, match="driftmap-drive/2") as err:
            parse_drive_json(json.dumps(obj), "drive.json")
        assert err.value.field == "format"

    def test_v2_without_a_lens_is_refused(self) -> None:
        with pytest.raises(BadInputError, match="for a camera with a lens") as err:
            parse_drive_json(V1_TEXT.replace("driftmap-drive/1", "driftmap-drive/2"), "drive.json")
        assert (err.value.line, err.value.field) == (2, "format")

    def test_a_lens_that_is_no_object_is_refused_naming_it(self) -> None:
        block = {**camera_to_json(make_camera()), "lens": "fisheye"}
        with pytest.raises(BadInputError, match="lens must be a JSON object") as err:
            parse_camera_block(block, "", "c.json")
        assert err.value.field == "camera.lens"

    def test_unknown_version_is_refused(self) -> None:
        with pytest.raises(BadInputError, match="driftmap-drive/1, driftmap-drive/2"):
            parse_drive_json(V1_TEXT.replace("driftmap-drive/1", "driftmap-drive/3"), "drive.json")

    @pytest.mark.parametrize(
        ("lens", "field"),
        [
            ({"K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "distortion": []}, "camera.lens.model"),
            (
                {"model": "wide", "K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "distortion": []},
                "camera.lens.model",
            ),
            ({"model": "pinhole", "K": [[1, 0, 0], [0, 1, 0]], "distortion": [0, 0, 0, 0]}, "camera.lens.K"),
            (
                {"model": "pinhole", "K": [[0, 0, 0], [0, 1, 0], [0, 0, 1]], "distortion": [0, 0, 0, 0]},
                "camera.lens.K",
            ),
            (
                {"model": "fisheye", "K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "distortion": [0, 0]},
                "camera.lens.distortion",
            ),
            (
                {"model": "fisheye", "K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "distortion": ["a"]},
                "camera.lens.distortion",
            ),
        ],
    )
    def test_bad_lens_names_the_key(self, lens: object, field: str) -> None:
        block = camera_to_json(make_camera())
        block["lens"] = lens
        text = json.dumps(block, indent=2)
        with pytest.raises(BadInputError) as err:
            parse_camera_block(json.loads(text), text, "calib.json")
        assert err.value.field == field
        assert err.value.file == "calib.json"


class TestCameraFile:
    def test_partial_block_round_trips_and_completes(self, tmp_path: Path) -> None:
        path = tmp_path / "camera.json"
        partial = {
            "width": 32,
            "height": 24,
            "lens": camera_to_json(dataclasses.replace(make_camera(), lens=LENS))["lens"],
        }
        write_camera_file(path, partial)
        block = read_camera_file(path)
        assert block == partial and complete_camera(block, path) is None
        full = camera_to_json(dataclasses.replace(make_camera(), lens=LENS))
        write_camera_file(path, full)
        camera = complete_camera(read_camera_file(path), path)
        assert camera == dataclasses.replace(make_camera(), lens=LENS)

    def test_wrapped_block_is_read(self, tmp_path: Path) -> None:
        path = tmp_path / "calib.json"
        path.write_text(json.dumps({"camera": {"width": 10, "height": 8}, "fps": 5}))
        assert read_camera_file(path) == {"width": 10, "height": 8}

    @pytest.mark.parametrize(
        ("text", "field"),
        [('{"width": -3}', "camera.width"), ('{"lens": 4}', "camera.lens"), ("[1]", "camera")],
    )
    def test_bad_file_names_field(self, tmp_path: Path, text: str, field: str) -> None:
        path = tmp_path / "camera.json"
        path.write_text(text)
        with pytest.raises(BadInputError) as err:
            read_camera_file(path)
        assert err.value.field == field and err.value.file == str(path)

    def test_missing_file_is_named(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match="camera file is missing"):
            read_camera_file(tmp_path / "nope.json")


class TestGroundPoints:
    def test_reads_points_in_order(self, tmp_path: Path) -> None:
        path = tmp_path / "points.csv"
        path.write_text("u,v,x,y\n10,200,3.5,1.25\n300.5,210,3.5,-1.25\n\n150,120,6,0\n")
        pixels, floor = read_ground_points(path)
        assert pixels.tolist() == [[10, 200], [300.5, 210], [150, 120]]
        assert floor.tolist() == [[3.5, 1.25], [3.5, -1.25], [6, 0]]

    @pytest.mark.parametrize(
        ("text", "line", "field"),
        [("u,v,x\n1,2,3\n", 1, "y"), ("u,v,x,y\n1,2,3,abc\n", 2, "y"), ("u,v,x,y\n1,2,3\n", 2, "y")],
    )
    def test_bad_rows_name_line_and_field(self, tmp_path: Path, text: str, line: int, field: str) -> None:
        path = tmp_path / "points.csv"
        path.write_text(text)
        with pytest.raises(BadInputError) as err:
            read_ground_points(path)
        assert (err.value.file, err.value.line, err.value.field) == (str(path), line, field)


class TestCalibrationImages:
    def test_images_and_video_frames(self, tmp_path: Path) -> None:
        image = np.arange(48 * 64, dtype=np.uint32).reshape(48, 64).astype(np.uint8)
        cv2.imwrite(str(tmp_path / "a.png"), image)
        [(name, gray)] = list(calibration_images([tmp_path / "a.png"]))
        assert name.endswith("a.png") and np.array_equal(gray, image)
        video = tmp_path / "board.avi"
        writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
        for _ in range(7):
            writer.write(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR))
        writer.release()
        names = [n for n, _ in calibration_images([video], every=3)]
        assert names == [f"{video}#frame 0", f"{video}#frame 3", f"{video}#frame 6"]

    def test_a_video_among_images_is_refused(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match="either image files or one video"):
            list(calibration_images([tmp_path / "a.png", tmp_path / "b.mp4"]))

    def test_unreadable_image_is_named(self, tmp_path: Path) -> None:
        (tmp_path / "bad.png").write_bytes(b"not a png")
        with pytest.raises(BadInputError) as err:
            list(calibration_images([tmp_path / "bad.png"]))
        assert err.value.file == str(tmp_path / "bad.png")
