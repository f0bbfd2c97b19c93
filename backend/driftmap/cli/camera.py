"""``driftmap camera``: set up a camera: lens intrinsics from a chessboard, the ground plane from floor points,
checks of the floor scale against a drive over a measured distance and of the mounting (``forward_sign``, the
turn's direction, the lever ``y_c``) against a drive that turns, and named camera profiles (``save``,
``profiles``) that drive imports and vehicles use.

The set-up commands read an optional ``--camera camera.json`` (a camera block in progress), add what they measure
and write ``--out``, so ``intrinsics`` then ``ground`` combine into one camera block (``docs/formats.md``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import typer
from numpy.typing import NDArray
from rich.table import Table

from driftmap.cli.common import JsonOption, console, err_console, open_storage, print_json, user_errors
from driftmap.core.imaging.lens import Lens
from driftmap.core.odometry.camera import CameraModel
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
from driftmap.formats.drive_json import camera_to_json
from driftmap.formats.frame_images import decode_gray
from driftmap.services.cameras import calibration as cal
from driftmap.services.cameras import drive_check
from driftmap.services.cameras import profiles as profile_service

LensName = Literal["pinhole", "fisheye"]
"""The names of :data:`~driftmap.core.imaging.lens.LENS_MODELS` (a test keeps them equal)."""
camera_app = typer.Typer(
    help="Set up a camera: lens intrinsics, the ground plane, a scale check.", no_args_is_help=True
)

_SIZE_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_ROI_RE = re.compile(r"^\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*$")


def _start(camera: Path | None) -> dict[str, Any]:
    return read_camera_file(camera) if camera is not None else {}


@camera_app.command("intrinsics")
def intrinsics(
    inputs: Annotated[list[Path], typer.Argument(help="Images of the board, or one video of it.")],
    board: Annotated[str, typer.Option("--board", help="Inner corners COLSxROWS, e.g. 9x6.")],
    square_m: Annotated[float, typer.Option("--square-m", help="Side of one square, metres.")],
    out: Annotated[Path, typer.Option("--out", help="camera.json to write.")],
    model: Annotated[LensName, typer.Option("--model", help="The lens model.")] = "pinhole",
    camera: Annotated[Path | None, typer.Option("--camera", help="camera.json to add the lens to.")] = None,
    every: Annotated[int, typer.Option("--every", help="Use every N-th frame of a video.")] = 15,
    marker_m: Annotated[
        float | None, typer.Option("--marker-m", help="A ChArUco board: side of its markers, metres.")
    ] = None,
    dictionary: Annotated[
        str | None, typer.Option("--dictionary", help="A ChArUco board's markers [default: DICT_4X4_50].")
    ] = None,
) -> None:
    """Calibrate the lens (K and distortion) from chessboard or ChArUco views; print the RMS per view."""
    with user_errors():
        target = cal.parse_board(board, square_m, "--board", marker_m=marker_m, dictionary=dictionary)
        block = _start(camera)
        found = cal.calibrate_intrinsics(calibration_images(inputs, every), target, model, field="IMAGES")
        for name in found.skipped:
            err_console.print(f"skipped {name}: no {target.describe()} board found")
        for name, rms in found.views:
            console.print(f"{name}: reprojection RMS {rms:.3f} px")
        block, stale = cal.add_lens(block, found, str(camera or "camera"))
        if stale:
            err_console.print(
                f"dropped {', '.join(stale)} (fitted for the previous lens): run `camera ground` again"
            )
        write_camera_file(out, block)
    k = found.lens.K
    console.print(
        f"{model} lens from {len(found.views)} views: fx {k[0][0]:.2f} fy {k[1][1]:.2f} cx {k[0][2]:.2f} "
        f"cy {k[1][2]:.2f} px, RMS {found.rms_px:.3f} px; wrote {out}"
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
            match = _SIZE_RE.match(size)
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
        try:
            found = cal.fit_ground_points(
                pixels, floor, int(block["width"]), int(block["height"]), _roi(roi, block), lens, "--roi"
            )
        except BadInputError as exc:
            if exc.field == "--roi":
                raise
            raise BadInputError(exc.reason, file=source, field=exc.field) from None
        fit = found.fit
        for k, residual in enumerate(fit.residuals_m, start=1):
            console.print(f"{'point' if points else 'corner'} {k}: residual {100 * residual:.1f} cm")
        block = cal.add_ground(block, found, y_c, forward_sign)
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
    target = cal.parse_board(board, square_m, field="--board")
    try:
        x, y, yaw_deg = (float(v) for v in at.split(","))
    except ValueError:
        raise BadInputError(f"must be X,Y,YAW_DEG, found {at!r}", field="--board-at") from None
    [(name, image)] = list(calibration_images([Path(str(image_path))]))
    return cal.board_ground_points(image, name, target, (x, y), math.radians(yaw_deg), lens)


def _roi(text: str | None, block: dict[str, Any]) -> list[int] | None:
    """The ROI from --roi, else the camera block's, else None (the clicked pixels' bounding box)."""
    if text is not None:
        match = _ROI_RE.match(text)
        if match is None:
            raise BadInputError(f"must be x,y,w,h in pixels, found {text!r}", field="--roi")
        return [int(g) for g in match.groups()]
    if isinstance(block.get("ground_roi"), list) and len(block["ground_roi"]) == 4:
        return [int(v) for v in block["ground_roi"]]
    return None


@camera_app.command("check")
def check(
    drive_dir: Annotated[
        Path, typer.Argument(help="A drive folder: straight over a measured distance, or with a turn.")
    ],
    distance_m: Annotated[
        float | None, typer.Option("--distance-m", help="A straight drive: the distance driven, metres.")
    ] = None,
    turn_deg: Annotated[
        float | None,
        typer.Option("--turn-deg", help="A drive that turns: the turn driven, degrees, + left, at least 20."),
    ] = None,
    camera: Annotated[
        Path | None, typer.Option("--camera", help="camera.json to check (default: the drive's camera).")
    ] = None,
    reverse: Annotated[bool, typer.Option("--reverse", help="The drive was in reverse.")] = False,
    out: Annotated[Path | None, typer.Option("--out", help="Write the corrected camera.json here.")] = None,
) -> None:
    """Check the floor scale (--distance-m) or the mounting: forward_sign, turn direction, lever y_c
    (--turn-deg) against a drive."""
    with user_errors():
        if (distance_m is None) == (turn_deg is None):
            raise BadInputError(
                "give --distance-m (a straight drive) or --turn-deg (a turn)", field="--distance-m"
            )
        folder = read_drive_folder(drive_dir)
        model = folder.meta.camera
        if camera is not None:
            model = complete_camera(read_camera_file(camera), camera) or _incomplete(camera)
        frames = (decode_gray(data, str(drive_dir)) for _row, data in iter_frame_images(folder))
        if distance_m is not None:
            result, fixed = drive_check.check_drive_scale(frames, model, distance_m, reverse=reverse)
            verdict = (
                f"odometry travelled {result.travelled_m:+.3f} m, measured {distance_m:.3f} m: floor lengths x "
                f"{result.ratio:.4f} ({100 * (result.ratio - 1):+.1f} %)"
                + ("; forward_sign is wrong" if result.sign_wrong else "")
            )
        else:
            assert turn_deg is not None
            turned, mounted = drive_check.check_drive_turn(
                frames, model, math.radians(turn_deg), reverse=reverse
            )
            verdict = _turn_verdict(turned)
            if mounted is None:
                err_console.print(verdict)
                raise BadInputError(
                    "the turn came out the wrong way: the ground plane is mirrored (floor y must be measured "
                    "to the camera's left); fit it again",
                    field="drive",
                )
            fixed = mounted
        if out is not None:
            write_camera_file(out, camera_to_json(fixed))
    console.print(verdict + (f"; wrote {out}" if out is not None else ""))


def _turn_verdict(check: drive_check.TurnCheck) -> str:
    """One paragraph: travel and forward_sign, the turn against the stated one, the levers found."""
    levers = []
    if check.fitted_y_c_m is not None and check.fitted_se_m is not None:
        levers.append(
            f"the floor's rotation puts y_c at {check.fitted_y_c_m:.2f} +- {check.fitted_se_m:.2f} m"
        )
    if check.turn_y_c_m is not None:
        levers.append(f"odometry turns through the stated angle with y_c {check.turn_y_c_m:.2f} m")
    found = "; ".join(levers) if levers else "no lever is found"
    return (
        f"odometry travelled {check.travelled_m:+.2f} m"
        + (" (forward_sign is wrong)" if check.sign_wrong else "")
        + f" and turned {math.degrees(check.turned_rad):+.1f} degrees for {math.degrees(check.stated_rad):+.1f}"
        + (" (the WRONG WAY)" if check.direction_wrong else f" (x {check.turn_ratio:.3f})")
        + f"; {found} (camera: {check.configured_y_c_m:.2f} m; the check's: {check.y_c_m:.2f} m)"
    )


@camera_app.command("save")
def save(
    name: Annotated[str, typer.Argument(help="Name of the camera profile.")],
    camera: Annotated[Path, typer.Argument(help="A complete camera.json.")],
    description: Annotated[str, typer.Option(help="Free text: the camera, its mount, the vehicles.")] = "",
) -> None:
    """Store a complete camera.json as a named camera profile (for vehicles and `drive import --profile`)."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        block = read_camera_file(camera)
        profile = profile_service.create_profile(session, name, block, description)
        console.print(f"camera profile {profile.name!r} saved (id {profile.id})")


@camera_app.command("profiles")
def profiles(as_json: JsonOption = False) -> None:
    """List the stored camera profiles (``--json``: each with its full camera block)."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        if as_json:
            rows = profile_service.list_profiles(session)
            print_json(
                [{"id": p.id, "name": p.name, "description": p.description, "camera": p.camera} for p in rows]
            )
            return
        table = Table("id", "name", "size", "lens", "description")
        for p in profile_service.list_profiles(session):
            lens = p.camera.get("lens") or {}
            size = f"{p.camera.get('width')}x{p.camera.get('height')}"
            table.add_row(str(p.id), p.name, size, str(lens.get("model", "none")), p.description)
        console.print(table)


def _incomplete(path: Path) -> CameraModel:
    raise BadInputError("is not a complete camera block (run `driftmap camera ground` first)", file=path)
