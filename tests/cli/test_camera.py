"""``driftmap camera intrinsics`` and ``driftmap camera ground`` end to end on rendered boards and points."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from driftmap.cli import app
from driftmap.core.imaging.calibration import Board
from driftmap.core.imaging.lens import Lens, distort_points
from driftmap.core.odometry.grid import apply_homography
from driftmap.core.odometry.scale_check import scale_camera
from driftmap.formats.camera_setup import complete_camera, read_camera_file, write_camera_file
from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.drive_json import camera_to_json, lens_to_json
from driftmap.formats.frame_images import encode_png
from driftmap.formats.records import DriveMeta, FrameRow
from tests.core.imaging.boards import CHARUCO, PINHOLE, board_poses, floor_pose, render_view
from tests.core.odometry.test_scale_check import straight_frames
from tests.core.odometry.test_turn_check import TRUE_Y_C_M, Y_C_TOL_M, mirrored, straight_then_turn
from tests.floor_frames import pinhole_camera

runner = CliRunner()
SCALE_REL_TOL = 0.02  # k_x, k_y through a calibrated (not the true) lens, exact floor points


@pytest.fixture(scope="module")
def board_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("boards")
    for k, (rvec, tvec) in enumerate(board_poses(5, 0.45)):
        cv2.imwrite(str(folder / f"view{k}.png"), render_view(PINHOLE, rvec, tvec, ss=2))
    cv2.imwrite(str(folder / "blank.png"), np.full((480, 640), 128, np.uint8))
    return folder


def _intrinsics(board_dir: Path, out: Path, *names: str) -> list[str]:
    files = [str(board_dir / n) for n in names] or sorted(str(p) for p in board_dir.glob("*.png"))
    return [*files, "--board", "8x6", "--square-m", "0.03", "--out", str(out)]


def _points(path: Path, clicks_640: np.ndarray) -> np.ndarray:
    """Floor points of the 320x240 test camera's homography seen at 640x480; raw clicks through PINHOLE."""
    hom = np.asarray(pinhole_camera().homography()) @ np.diag([0.5, 0.5, 1.0])
    floor = apply_homography(hom, clicks_640)
    raw = distort_points(PINHOLE, clicks_640)
    rows = "".join(f"{u},{v},{x},{y}\n" for (u, v), (x, y) in zip(raw, floor, strict=True))
    path.write_text("u,v,x,y\n" + rows)
    return hom


class TestIntrinsicsCommand:
    def test_calibrates_and_names_skipped_images(self, board_dir: Path, tmp_path: Path) -> None:
        out = tmp_path / "camera.json"
        result = runner.invoke(app, ["camera", "intrinsics", *_intrinsics(board_dir, out)])
        assert result.exit_code == 0, result.output
        assert "blank.png: no 8x6 board found" in result.output
        assert result.output.count("reprojection RMS") == 5
        block = read_camera_file(out)
        assert (block["width"], block["height"], block["lens"]["model"]) == (640, 480, "pinhole")
        assert abs(block["lens"]["K"][0][0] / PINHOLE.K[0][0] - 1) < 0.01

    def test_too_few_views_is_an_error_naming_the_count(self, board_dir: Path, tmp_path: Path) -> None:
        args = _intrinsics(board_dir, tmp_path / "c.json", "view0.png", "view1.png", "blank.png")
        result = runner.invoke(app, ["camera", "intrinsics", *args])
        assert result.exit_code == 1
        assert "found in 2 view(s); calibration needs at least 3" in result.output
        assert not (tmp_path / "c.json").exists()

    def test_charuco_board(self, tmp_path: Path) -> None:
        """A ChArUco board is named by --marker-m (and --dictionary); a chessboard view is not one."""
        for k, (rvec, tvec) in enumerate(board_poses(4, 0.45, board=CHARUCO)):
            cv2.imwrite(str(tmp_path / f"charuco{k}.png"), render_view(PINHOLE, rvec, tvec, CHARUCO, ss=2))
        chess_rvec, chess_tvec = board_poses(1, 0.45)[0]
        cv2.imwrite(str(tmp_path / "chess.png"), render_view(PINHOLE, chess_rvec, chess_tvec, ss=2))
        out = tmp_path / "camera.json"
        files = sorted(str(p) for p in tmp_path.glob("*.png"))
        board = ["--board", "9x6", "--square-m", "0.03", "--marker-m", "0.022", "--dictionary", "DICT_4X4_50"]
        result = runner.invoke(app, ["camera", "intrinsics", *files, *board, "--out", str(out)])
        assert result.exit_code == 0, result.output
        assert "chess.png: no 9x6 ChArUco board found" in result.output
        assert result.output.count("reprojection RMS") == 4
        assert abs(read_camera_file(out)["lens"]["K"][0][0] / PINHOLE.K[0][0] - 1) < 0.01
        bad = [
            "--board",
            "9x6",
            "--square-m",
            "0.03",
            "--marker-m",
            "0.04",
            "--out",
            str(tmp_path / "x.json"),
        ]
        result = runner.invoke(app, ["camera", "intrinsics", *files, *bad])
        assert (
            result.exit_code == 1
            and "marker_m" in result.output
            and "less than the square side" in result.output
        )

    def test_bad_board_option(self, board_dir: Path, tmp_path: Path) -> None:
        args = _intrinsics(board_dir, tmp_path / "c.json", "view0.png")
        result = runner.invoke(app, ["camera", "intrinsics", *args[:-5], "--board", "8by6", *args[-4:]])
        assert result.exit_code == 2 and "--board" in result.output


class TestGroundCommand:
    def test_intrinsics_then_ground_make_one_camera(self, board_dir: Path, tmp_path: Path) -> None:
        lens_file, out, points = tmp_path / "lens.json", tmp_path / "camera.json", tmp_path / "points.csv"
        assert runner.invoke(app, ["camera", "intrinsics", *_intrinsics(board_dir, lens_file)]).exit_code == 0
        clicks = np.array([[40.0, 210.0], [600.0, 210.0], [620.0, 470.0], [20.0, 470.0], [320.0, 330.0]])
        _points(points, clicks)
        args = ["camera", "ground", str(points), "--camera", str(lens_file), "--out", str(out)]
        result = runner.invoke(app, [*args, "--roi", "120,260,400,180", "--y-c", "1.5"])
        assert result.exit_code == 0, result.output
        assert "point 5: residual" in result.output
        camera = complete_camera(read_camera_file(out), out)
        assert camera is not None and camera.lens is not None and camera.y_c_m == 1.5
        truth = pinhole_camera()
        assert abs(camera.k_x_m_per_px / (truth.k_x_m_per_px / 2) - 1) < SCALE_REL_TOL
        assert abs(camera.k_y_m_per_px / (truth.k_y_m_per_px / 2) - 1) < SCALE_REL_TOL

    def test_a_new_lens_drops_the_fitted_ground(self, board_dir: Path, tmp_path: Path) -> None:
        lens_file, out, points = tmp_path / "lens.json", tmp_path / "camera.json", tmp_path / "points.csv"
        assert runner.invoke(app, ["camera", "intrinsics", *_intrinsics(board_dir, lens_file)]).exit_code == 0
        _points(points, np.array([[40.0, 210.0], [600.0, 210.0], [620.0, 470.0], [20.0, 470.0]]))
        args = ["camera", "ground", str(points), "--camera", str(lens_file), "--out", str(out)]
        assert runner.invoke(app, [*args, "--roi", "120,260,400,180"]).exit_code == 0
        views = ("view0.png", "view1.png", "view2.png")
        again = _intrinsics(board_dir, out, *views)
        result = runner.invoke(app, ["camera", "intrinsics", *again, "--camera", str(out)])
        assert result.exit_code == 0 and "dropped k_x, k_y, y_h, ground_homography" in result.output
        block = read_camera_file(out)
        assert "k_x" not in block and block["ground_roi"] == [120, 260, 400, 180]
        assert complete_camera(block, out) is None

    def test_collinear_points_name_the_file_and_points(self, tmp_path: Path) -> None:
        points = tmp_path / "points.csv"
        points.write_text("u,v,x,y\n10,200,3,1\n100,200,3,0\n200,200,3,-1\n50,230,2,0.5\n")
        result = runner.invoke(
            app, ["camera", "ground", str(points), "--size", "320x240", "--out", str(tmp_path / "c.json")]
        )
        assert result.exit_code == 1
        assert str(points) in result.output and "points 1, 2, 3 are collinear" in result.output

    def test_unknown_frame_size_is_refused(self, tmp_path: Path) -> None:
        points = tmp_path / "points.csv"
        points.write_text("u,v,x,y\n")
        result = runner.invoke(app, ["camera", "ground", str(points), "--out", str(tmp_path / "c.json")])
        assert result.exit_code == 2 and "--size" in result.output


class TestGroundFromABoard:
    def test_board_on_the_floor(self, tmp_path: Path) -> None:
        board = Board(8, 5, 0.25)
        lens = Lens(
            "pinhole", ((500.0, 0.0, 320.0), (0.0, 500.0, 240.0), (0.0, 0.0, 1.0)), (-0.2, 0.05, 0.0, 0.0)
        )
        image = tmp_path / "floor.png"
        cv2.imwrite(
            str(image), render_view(lens, *floor_pose(board, (3.0, 0.2), 1.2), board=board, size=(640, 480))
        )
        lens_file, out = tmp_path / "lens.json", tmp_path / "camera.json"
        write_camera_file(lens_file, {"width": 640, "height": 480, "lens": lens_to_json(lens)})
        args = [
            "--board-image",
            str(image),
            "--board",
            "8x5",
            "--square-m",
            "0.25",
            "--board-at",
            "3,0.2,68.755",
        ]
        result = runner.invoke(
            app,
            [
                "camera",
                "ground",
                *args,
                "--camera",
                str(lens_file),
                "--roi",
                "120,260,400,180",
                "--out",
                str(out),
            ],
        )
        assert result.exit_code == 0, result.output
        assert "corner 40: residual" in result.output
        camera = complete_camera(read_camera_file(out), out)
        assert camera is not None
        truth = pinhole_camera()
        assert abs(camera.k_x_m_per_px / (truth.k_x_m_per_px / 2) - 1) < SCALE_REL_TOL

    def test_points_or_board_not_both(self, tmp_path: Path) -> None:
        points = tmp_path / "points.csv"
        points.write_text("u,v,x,y\n")
        args = ["camera", "ground", str(points), "--board-image", str(points), "--size", "64x48"]
        result = runner.invoke(app, [*args, "--out", str(tmp_path / "c.json")])
        assert result.exit_code == 1 and "either a points CSV or --board-image" in result.output

    def test_board_not_found_names_the_image(self, tmp_path: Path) -> None:
        image = tmp_path / "empty.png"
        cv2.imwrite(str(image), np.full((48, 64), 128, np.uint8))
        args = ["--board-image", str(image), "--board", "8x5", "--square-m", "0.25", "--board-at", "3,0,0"]
        result = runner.invoke(
            app, ["camera", "ground", *args, "--size", "64x48", "--out", str(tmp_path / "c.json")]
        )
        assert (
            result.exit_code == 1 and "empty.png" in result.output and "no 8x5 board found" in result.output
        )


class TestCheckCommand:
    def test_scale_from_a_measured_drive(self, tmp_path: Path) -> None:
        wrong = scale_camera(pinhole_camera(), 1.08)
        frames = straight_frames()
        rows = [FrameRow(i, i / 10) for i in range(len(frames))]
        drive = tmp_path / "straight"
        write_drive_folder(
            drive, DriveMeta("straight", "mapping", 10.0, wrong), rows, (encode_png(f) for f in frames)
        )
        out = tmp_path / "fixed.json"
        result = runner.invoke(app, ["camera", "check", str(drive), "--distance-m", "2.0", "--out", str(out)])
        assert result.exit_code == 0, result.output
        assert "floor lengths x 0.92" in result.output
        fixed = complete_camera(read_camera_file(out), out)
        assert fixed is not None
        assert fixed.k_y_m_per_px == pytest.approx(pinhole_camera().k_y_m_per_px, rel=0.01)

    def test_mounting_from_a_drive_that_turns(self, tmp_path: Path) -> None:
        frames = straight_then_turn()
        drive, out = tmp_path / "turn", tmp_path / "mounted.json"
        meta = DriveMeta("turn", "mapping", 10.0, dataclasses.replace(pinhole_camera(), forward_sign=-1))
        write_drive_folder(
            drive, meta, [FrameRow(i, i / 10) for i in range(len(frames))], map(encode_png, frames)
        )
        result = runner.invoke(app, ["camera", "check", str(drive), "--turn-deg", "45", "--out", str(out)])
        assert result.exit_code == 0, result.output
        assert (
            "(forward_sign is wrong)" in result.output
            and "the floor's rotation puts y_c at 0." in result.output
        )
        fixed = complete_camera(read_camera_file(out), out)
        assert fixed is not None and fixed.forward_sign == 1
        assert fixed.y_c_m == pytest.approx(TRUE_Y_C_M, abs=Y_C_TOL_M)
        mirror_file = tmp_path / "mirrored.json"
        write_camera_file(mirror_file, camera_to_json(mirrored(pinhole_camera())))
        args = ["--turn-deg", "45", "--camera", str(mirror_file), "--out", str(tmp_path / "no.json")]
        result = runner.invoke(app, ["camera", "check", str(drive), *args])
        assert result.exit_code == 1 and "the WRONG WAY" in result.output and "mirrored" in result.output
        assert not (tmp_path / "no.json").exists()
        result = runner.invoke(app, ["camera", "check", str(drive), "--turn-deg", "45", "--distance-m", "2"])
        assert result.exit_code == 2 and "--turn-deg" in result.output

    def test_distance_must_be_positive(self, tmp_path: Path) -> None:
        frames = straight_frames(n=2)
        drive = tmp_path / "d"
        rows = [FrameRow(i, i / 10) for i in range(2)]
        write_drive_folder(
            drive, DriveMeta("d", "mapping", 10.0, pinhole_camera()), rows, (encode_png(f) for f in frames)
        )
        result = runner.invoke(app, ["camera", "check", str(drive), "--distance-m", "0"])
        assert result.exit_code == 1 and "distance_m" in result.output
