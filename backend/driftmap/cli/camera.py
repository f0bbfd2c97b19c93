"""``driftmap camera``: set up a camera: lens intrinsics from a chessboard, the ground plane from floor points,
and a check of the floor scale and ``forward_sign`` against a drive over a measured distance.

The set-up commands read an optional ``--camera camera.json`` (a camera block in progress), add what they measure
and write ``--out``, so ``intrinsics`` then ``ground`` combine into one camera block (``docs/formats.md``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, cast

import numpy as np
import typer
from numpy.typing import NDArray

from driftmap.cli.common import console, err_console, user_errors
from driftmap.core.imaging.calibration import Board, calibrate_lens, find_board
from driftmap.core.imaging.lens import LENS_MODELS, Lens, LensModel
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import dead_reckon
from driftmap.core.odometry.ground_setup import board_floor_points, fit_ground
from driftmap.core.odometry.scale_check import check_scale, scale_camera
from driftmap.errors import BadInputError
from driftmap.formats.camera_setup import (
    calibration_images,
    complete_camera,
    lens_of,
    read_camera_file,
    read_ground_points,
    write_camera_file,
)
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder
from driftmap.formats.drive_json import camera_to_json, lens_to_json
from driftmap.formats.frame_images import decode_gray

camera_app = typer.Typer(
    help="Set up a camera: lens intrinsics, the ground plane, a scale check.", no_args_is_help=True
)

_FITTED_GROUND = ("k_x", "k_y", "y_h", "ground_homography")  # refer to the undistorted image of one lens
_BOARD_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_ROI_RE = re.compile(r"^\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*$")


def _board(text: str, square_m: float) -> Board:
    match = _BOARD_RE.match(text)
    if match is None:
        raise BadInputError(f"must be COLSxROWS inner corners, e.g. 9x6, found {text!r}", field="--board")
    return Board(int(match.group(1)), int(match.group(2)), square_m)


def _start(camera: Path | None) -> dict[str, Any]:
    return read_camera_file(camera) if camera is not None else {}


@camera_app.command("intrinsics")
def intrinsics(
    inputs: Annotated[list[Path], typer.Argument(help="Images of the board, or one video of it.")],
    board: Annotated[str, typer.Option("--board", help="Inner corners COLSxROWS, e.g. 9x6.")],
    square_m: Annotated[float, typer.Option("--square-m", help="Side of one square, metres.")],
    out: Annotated[Path, typer.Option("--out", help="camera.json to write.")],
    model: Annotated[str, typer.Option("--model", help="pinhole or fisheye.")] = "pinhole",
    camera: Annotated[Path | None, typer.Option("--camera", help="camera.json to add the lens to.")] = None,
    every: Annotated[int, typer.Option("--every", help="Use every N-th frame of a video.")] = 15,
) -> None:
    """Calibrate the lens (K and distortion) from chessboard views; print the reprojection RMS per view."""
    with user_errors():
        if model not in LENS_MODELS:
            raise BadInputError(f"must be one of {', '.join(LENS_MODELS)}, found {model!r}", field="--model")
        target = _board(board, square_m)
        block = _start(camera)
        names: list[str] = []
        views = []
        size: tuple[int, int] | None = None
        for name, image in calibration_images(inputs, every):
            shape = (image.shape[1], image.shape[0])
            if size is not None and shape != size:
                raise BadInputError(
                    f"is {shape[0]}x{shape[1]}, the first image {size[0]}x{size[1]}", file=name
                )
            size = shape
            corners = find_board(image, target)
            if corners is None:
                err_console.print(f"skipped {name}: no {board} board found")
                continue
            names.append(name)
            views.append(corners)
        if size is None:
            raise BadInputError("no images given", field="IMAGES")
        if (block.get("width"), block.get("height")) not in ((None, None), size):
            raise BadInputError(
                f"says {block.get('width')}x{block.get('height')} but the images are {size[0]}x{size[1]}",
                file=camera,
                field="camera.width",
            )
        result = calibrate_lens(views, target, size, cast(LensModel, model))
        for name, rms in zip(names, result.view_rms_px, strict=True):
            console.print(f"{name}: reprojection RMS {rms:.3f} px")
        stale = [k for k in _FITTED_GROUND if k in block]
        if stale and block.get("lens") != lens_to_json(result.lens):
            for key in stale:  # fitted on the old undistorted image: refit with `driftmap camera ground`
                del block[key]
            err_console.print(
                f"dropped {', '.join(stale)} (fitted for the previous lens): run `camera ground` again"
            )
        block.update({"width": size[0], "height": size[1], "lens": lens_to_json(result.lens)})
        write_camera_file(out, block)
    k = result.lens.K
    console.print(
        f"{model} lens from {len(names)} views: fx {k[0][0]:.2f} fy {k[1][1]:.2f} cx {k[0][2]:.2f} "
        f"cy {k[1][2]:.2f} px, RMS {result.rms_px:.3f} px; wrote {out}"
    )


@camera_app.command("ground")
def ground(
    out: Annotated[Path, typer.Option("--out", help="camera.json to write.")],
    points: Annotated[
        Path | None, typer.Argument(help="CSV u,v,x,y: floor marks in a frame and their floor metres.")
    ] = None,
    board_image: Annotated[
        Path | None, typer.Option("--board-image", help="A frame with a chessboard lying on the floor.")
    ] = None,
    board: Annotated[str | None, typer.Option("--board", help="Its inner corners COLSxROWS.")] = None,
    square_m: Annotated[float | None, typer.Option("--square-m", help="Its square side, metres.")] = None,
    board_at: Annotated[
        str | None, typer.Option("--board-at", help="X,Y,YAW_DEG: its centre (metres) and row direction.")
    ] = None,
    camera: Annotated[Path | None, typer.Option("--camera", help="camera.json to add the ground to.")] = None,
    roi: Annotated[
        str | None,
        typer.Option("--roi", help="Ground ROI x,y,w,h (undistorted image); default: the points' box."),
    ] = None,
    size: Annotated[str | None, typer.Option("--size", help="Frame WxH when --camera gives none.")] = None,
    y_c: Annotated[float | None, typer.Option("--y-c", help="Rear axle to camera, metres.")] = None,
    forward_sign: Annotated[int | None, typer.Option("--forward-sign", help="+1 or -1.")] = None,
) -> None:
    """Fit the ground homography, k_x, k_y and y_h from >= 4 clicked floor points or a board on the floor."""
    with user_errors():
        block = _start(camera)
        if size is not None:
            match = _BOARD_RE.match(size)
            if match is None:
                raise BadInputError(f"must be WxH, found {size!r}", field="--size")
            block.update({"width": int(match.group(1)), "height": int(match.group(2))})
        if block.get("width") is None or block.get("height") is None:
            raise BadInputError(
                "the frame size is unknown: give --camera with width/height or --size", field="--size"
            )
        lens = lens_of(block, camera or "camera")
        if (points is None) == (board_image is None):
            raise BadInputError("give either a points CSV or --board-image", field="POINTS")
        source: Path | None = points or board_image
        if points is not None:
            pixels, floor = read_ground_points(points)
        else:
            pixels, floor = _board_points(source, board, square_m, board_at, lens)
        rect = _roi(roi, block, pixels)
        try:
            fit = fit_ground(pixels, floor, rect, lens)
        except BadInputError as exc:
            raise BadInputError(exc.reason, file=source, field=exc.field) from None
        for k, residual in enumerate(fit.residuals_m, start=1):
            console.print(f"{'point' if points else 'corner'} {k}: residual {100 * residual:.1f} cm")
        block.update(
            {
                "ground_roi": list(rect),
                "k_x": fit.k_x_m_per_px,
                "k_y": fit.k_y_m_per_px,
                "y_h": fit.y_h_m,
                "ground_homography": [list(r) for r in fit.homography],
            }
        )
        block["y_c"] = y_c if y_c is not None else block.get("y_c", 0.0)
        block["forward_sign"] = forward_sign if forward_sign is not None else block.get("forward_sign", 1)
        write_camera_file(out, block)
        done = complete_camera(block, out) is not None
    console.print(
        f"k_x {fit.k_x_m_per_px:.5f} k_y {fit.k_y_m_per_px:.5f} m/px, y_h {fit.y_h_m:.3f} m; wrote {out}"
        + ("" if done else " (incomplete camera block)")
    )


def _board_points(
    image_path: Path | None, board: str | None, square_m: float | None, at: str | None, lens: Lens | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Corner pixels of a board lying on the floor in one frame, and their floor positions."""
    if board is None or square_m is None or at is None:
        raise BadInputError("--board-image needs --board, --square-m and --board-at", field="--board-at")
    target = _board(board, square_m)
    try:
        x, y, yaw_deg = (float(v) for v in at.split(","))
    except ValueError:
        raise BadInputError(f"must be X,Y,YAW_DEG, found {at!r}", field="--board-at") from None
    [(name, image)] = list(calibration_images([Path(str(image_path))]))
    corners = find_board(image, target)
    if corners is None:
        raise BadInputError(f"no {board} board found", file=name)
    try:
        floor = board_floor_points(corners, target, (x, y), math.radians(yaw_deg), lens)
    except BadInputError as exc:
        raise BadInputError(exc.reason, file=name, field=exc.field) from None
    return corners, floor


def _roi(text: str | None, block: dict[str, Any], pixels: Any) -> tuple[int, int, int, int]:
    """The ROI from --roi, else the camera block's, else the bounding box of the clicked pixels."""
    if text is not None:
        match = _ROI_RE.match(text)
        if match is None:
            raise BadInputError(f"must be x,y,w,h in pixels, found {text!r}", field="--roi")
        x, y, w, h = (int(g) for g in match.groups())
    elif isinstance(block.get("ground_roi"), list) and len(block["ground_roi"]) == 4:
        x, y, w, h = (int(v) for v in block["ground_roi"])
    else:
        lo, hi = pixels.min(axis=0), pixels.max(axis=0)
        x, y = max(int(lo[0]), 0), max(int(lo[1]), 0)
        w = min(int(hi[0]) + 1, int(block["width"])) - x
        h = min(int(hi[1]) + 1, int(block["height"])) - y
    width, height = int(block["width"]), int(block["height"])
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise BadInputError(
            f"[{x}, {y}, {w}, {h}] does not lie inside the {width}x{height} frame", field="--roi"
        )
    return (x, y, w, h)


@camera_app.command("check")
def check(
    drive_dir: Annotated[
        Path, typer.Argument(help="A drive folder: a straight drive over a measured distance.")
    ],
    distance_m: Annotated[float, typer.Option("--distance-m", help="The distance driven, metres.")],
    camera: Annotated[
        Path | None, typer.Option("--camera", help="camera.json to check (default: the drive's camera).")
    ] = None,
    reverse: Annotated[bool, typer.Option("--reverse", help="The drive was in reverse.")] = False,
    out: Annotated[Path | None, typer.Option("--out", help="Write the corrected camera.json here.")] = None,
) -> None:
    """Check the floor scale and forward_sign against a drive over a measured distance."""
    with user_errors():
        folder = read_drive_folder(drive_dir)
        model = folder.meta.camera
        if camera is not None:
            model = complete_camera(read_camera_file(camera), camera) or _incomplete(camera)
        frames = (decode_gray(data, str(drive_dir)) for _row, data in iter_frame_images(folder))
        result = check_scale(dead_reckon(frames, model).wTi, distance_m, reverse=reverse)
        fixed = scale_camera(model, result.ratio, flip_sign=result.sign_wrong)
        if out is not None:
            write_camera_file(out, camera_to_json(fixed))
    console.print(
        f"odometry travelled {result.travelled_m:+.3f} m, measured {distance_m:.3f} m: floor lengths x "
        f"{result.ratio:.4f} ({100 * (result.ratio - 1):+.1f} %)"
        + ("; forward_sign is wrong" if result.sign_wrong else "")
        + (f"; wrote {out}" if out is not None else "")
    )


def _incomplete(path: Path) -> CameraModel:
    raise BadInputError("is not a complete camera block (run `driftmap camera ground` first)", file=path)
