"""Camera set-up: lens intrinsics from chessboard views, the ground plane from clicked floor points, and
named camera profiles (surveyors and admins write, every user reads).

``POST /api/cameras/intrinsics`` (multipart) takes ``images`` (PNG or JPEG files) or one ``video`` of a
chessboard, the board's inner corners ``board`` (``COLSxROWS``), ``square_m`` and ``model`` (``pinhole`` or
``fisheye``), and answers the camera block's ``lens``, ``width`` and ``height`` with each view's reprojection
RMS and the names of the images the board was not found in. Too few views with the board, a file that is not
an image, images of different sizes: 422 naming ``images`` (or ``video``). Each image may be as large as a
frame (``max_frame_bytes``), a video as large as an upload (``max_upload_bytes``).

``POST /api/cameras/ground`` (JSON) fits ``ground_homography``, ``k_x``, ``k_y`` and ``y_h`` to four or more
clicked floor points and answers each point's residual; duplicated or collinear points are 422 naming
``points`` and the points by number (from 1). Neither route stores anything: put the values into a camera
block and store it on a vehicle (``PUT /api/vehicles/{id}/camera``) or as a profile.

``POST /api/cameras/preview`` (multipart) takes one ``frame`` (PNG or JPEG, as recorded, at most
``max_frame_bytes``) and ``camera``, the camera block in progress as JSON text (``width``, ``height``, optional
``lens``, ``ground_roi``, ``ground_homography``), and answers the frame's undistorted image and, with a ground
homography, the bird's-eye view of the floor around the ROI's footprint, both as base64 PNG. A file that is not
an image or not ``width`` x ``height``: 422 naming ``frame``; a bad block or an ROI reaching above the
horizon: 422 naming ``camera.<key>``.

``POST /api/drives/{id}/camera-check`` (JSON) checks a camera against a stored drive: the floor scale from a
straight drive over a measured ``distance_m``, or the mounting (``forward_sign``, the turn's direction, the
lever ``y_c``) from a drive that turns through ``turn_deg``; it answers the figures and the corrected block.

``/api/camera-profiles``: stored, named camera blocks (global, not per site), checked as a drive import checks
its ``camera`` block (422 naming ``camera.<key>``; nothing stored). ``PUT /api/vehicles/{id}/camera`` with
``{"profile": <id>}`` gives a vehicle a copy of a profile's block.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Depends, File, Form, Query, UploadFile, status

from driftmap.api.cameras_schemas import (
    CameraCheckRead,
    CameraCheckRequest,
    CameraProfileCreate,
    CameraProfileRead,
    CameraProfileUpdate,
    GroundRead,
    GroundRequest,
    IntrinsicsRead,
    IntrinsicsView,
    PreviewRead,
    preview_read,
    profile_read,
)
from driftmap.api.deps import SURVEYOR, VIEWER, SessionDep, SettingsDep, StorageDep
from driftmap.api.drives import drive_by_id
from driftmap.api.input_types import Count, Finite, Id
from driftmap.api.schemas_access import CameraLens
from driftmap.api.schemas_data import Page, paged
from driftmap.api.upload_limits import check_content_length, read_limited
from driftmap.config import Settings
from driftmap.core.imaging.calibration import Board
from driftmap.errors import BadInputError
from driftmap.formats.camera_setup import video_frames
from driftmap.formats.drive_json import lens_to_json
from driftmap.services import uploads
from driftmap.services.cameras import calibration as cal
from driftmap.services.cameras import drive_check
from driftmap.services.cameras import preview as preview_service
from driftmap.services.cameras import profiles as profile_service

router = APIRouter(tags=["cameras"])
MAX_BOARD_IMAGES = 500  # images of one intrinsics calibration
MAX_SQUARE_M = 10.0  # largest chessboard square, metres
MAX_BLOCK_CHARS = 20_000  # a camera block as JSON text


@router.post("/cameras/intrinsics", dependencies=[Depends(SURVEYOR), Depends(check_content_length)])
def post_intrinsics(
    settings: SettingsDep,
    board: Annotated[str, Form(max_length=20, description="Inner corners COLSxROWS, e.g. 9x6.")],
    square_m: Annotated[Finite, Form(gt=0, le=MAX_SQUARE_M, description="Side of one square, metres.")],
    model: Annotated[Literal["pinhole", "fisheye"], Form(description="The lens model.")] = "pinhole",
    images: Annotated[list[UploadFile] | None, File(description="PNG or JPEG views of the board.")] = None,
    video: Annotated[
        UploadFile | None, File(description="One video of the board, instead of images.")
    ] = None,
    every: Annotated[int, Form(ge=1, le=10_000, description="Use every N-th frame of the video.")] = 15,
    marker_m: Annotated[
        Finite | None,
        Form(gt=0, le=MAX_SQUARE_M, description="A ChArUco board: side of its markers, metres."),
    ] = None,
    dictionary: Annotated[
        str | None,
        Form(
            max_length=20, description="A ChArUco board's marker dictionary, e.g. DICT_4X4_50 (the default)."
        ),
    ] = None,
) -> IntrinsicsRead:
    """Calibrate a lens from chessboard or ChArUco views (images or one video); each view's reprojection RMS,
    pixels."""
    target = cal.parse_board(board, square_m, marker_m=marker_m, dictionary=dictionary)
    if bool(images) == (video is not None):
        raise BadInputError("give either images or one video of the board", field="images")
    if images:
        if len(images) > MAX_BOARD_IMAGES:
            raise BadInputError(f"{len(images)} images, at most {MAX_BOARD_IMAGES}", field="images")
        files = [(_name(f, "image"), f) for f in images]
        data = ((name, read_limited(f, settings.max_frame_bytes, name)) for name, f in files)  # one at a time
        decoded = cal.decode_images(data, max_pixels=settings.max_frame_pixels)
        found = cal.calibrate_intrinsics(decoded, target, model)
    else:
        assert video is not None
        found = _video_intrinsics(video, settings, target, model, every)
    return IntrinsicsRead(
        lens=CameraLens.model_validate(lens_to_json(found.lens)),
        width=found.width_px,
        height=found.height_px,
        rms_px=found.rms_px,
        views=[IntrinsicsView(name=n, rms_px=r) for n, r in found.views],
        skipped=list(found.skipped),
    )


def _name(file: UploadFile, default: str) -> str:
    return Path(file.filename or default).name or default


def _video_intrinsics(
    video: UploadFile, settings: Settings, target: Board, model: str, every: int
) -> cal.Intrinsics:
    """Calibrate from every ``every``-th frame of an uploaded video (saved to scratch, then removed)."""
    name = _name(video, "video")
    scratch = uploads.scratch_dir(settings.data_dir, "camera-")
    try:
        path = scratch / f"video{Path(name).suffix.lower()}"
        uploads.save_upload(video.file, path, max_bytes=settings.max_upload_bytes, filename=name)
        frames = video_frames(path, every, name)
        try:
            return cal.calibrate_intrinsics(
                frames, target, model, field="video", max_pixels=settings.max_frame_pixels
            )
        except BadInputError as exc:
            raise type(exc)(exc.reason, file=exc.file, field=exc.field or "video") from None
    finally:
        uploads.remove_tree(scratch)


@router.post("/cameras/ground", dependencies=[Depends(SURVEYOR)])
def post_ground(body: GroundRequest) -> GroundRead:
    """Fit the ground plane to >= 4 clicked floor points; the camera block's ground values and residuals."""
    lens = cal.parse_lens(body.lens.model_dump()) if body.lens is not None else None
    pixels = np.array([[p.px, p.py] for p in body.points], dtype=np.float64).reshape(-1, 2)
    floor = np.array([[p.x_m, p.y_m] for p in body.points], dtype=np.float64).reshape(-1, 2)
    ground = cal.fit_ground_points(pixels, floor, body.width, body.height, body.ground_roi, lens)
    return GroundRead(**ground.block_values(), residuals_m=[float(r) for r in ground.fit.residuals_m])


@router.post("/drives/{drive_id}/camera-check", dependencies=[Depends(SURVEYOR)])
def post_camera_check(
    drive_id: Id, body: CameraCheckRequest, session: SessionDep, storage: StorageDep
) -> CameraCheckRead:
    """Check a camera (the drive's, or ``camera``) against a stored drive: the floor scale (``distance_m``, a
    straight drive) or the mounting (``turn_deg``, a drive that turns); the camera block as corrected."""
    drive = drive_by_id(session, drive_id)
    found = drive_check.check_stored_drive(
        session,
        storage.blobs,
        drive,
        distance_m=body.distance_m,
        turn_deg=body.turn_deg,
        reverse=body.reverse,
        camera=body.camera,
    )
    common = {"y_c_m": found.y_c_m, "camera": found.camera}
    if found.scale is not None:
        scale = found.scale
        return CameraCheckRead(
            travelled_m=scale.travelled_m, sign_wrong=scale.sign_wrong, ratio=scale.ratio, turned_deg=None,
            direction_wrong=None, fitted_y_c_m=None, fitted_se_m=None, turn_y_c_m=None, **common,
        )  # fmt: skip
    turn = found.turn
    assert turn is not None
    return CameraCheckRead(
        travelled_m=turn.travelled_m, sign_wrong=turn.sign_wrong, ratio=None,
        turned_deg=math.degrees(turn.turned_rad), direction_wrong=turn.direction_wrong,
        fitted_y_c_m=turn.fitted_y_c_m, fitted_se_m=turn.fitted_se_m, turn_y_c_m=turn.turn_y_c_m, **common,
    )  # fmt: skip


@router.post("/cameras/preview", dependencies=[Depends(SURVEYOR), Depends(check_content_length)])
def post_preview(
    settings: SettingsDep,
    frame: Annotated[UploadFile, File(description="One frame as recorded, PNG or JPEG.")],
    camera: Annotated[
        str, Form(max_length=MAX_BLOCK_CHARS, description="The camera block in progress, JSON text.")
    ],
) -> PreviewRead:
    """A frame's undistorted image and the bird's-eye view of its floor (with a ground homography), PNG."""
    block = preview_service.parse_preview_camera(camera)
    name = _name(frame, "frame")
    data = read_limited(frame, settings.max_frame_bytes, name)
    return preview_read(preview_service.make_preview(data, name, block, settings.max_frame_pixels))


@router.get("/camera-profiles", dependencies=[Depends(VIEWER)])
def list_profiles(
    session: SessionDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
) -> Page[CameraProfileRead]:
    """Every camera profile, oldest first."""
    return paged(profile_service.list_profiles(session), offset, limit, profile_read)


@router.post("/camera-profiles", status_code=status.HTTP_201_CREATED, dependencies=[Depends(SURVEYOR)])
def create_profile(body: CameraProfileCreate, session: SessionDep) -> CameraProfileRead:
    """Store a named camera block (checked as a drive import checks it)."""
    return profile_read(profile_service.create_profile(session, body.name, body.camera, body.description))


@router.get("/camera-profiles/{profile_id}", dependencies=[Depends(VIEWER)])
def get_profile(profile_id: Id, session: SessionDep) -> CameraProfileRead:
    """One camera profile."""
    return profile_read(profile_service.get_profile(session, profile_id))


@router.put("/camera-profiles/{profile_id}", dependencies=[Depends(SURVEYOR)])
def update_profile(profile_id: Id, body: CameraProfileUpdate, session: SessionDep) -> CameraProfileRead:
    """Change a profile's name, description or camera block (vehicles already given it keep their copy)."""
    profile = profile_service.get_profile(session, profile_id)
    updated = profile_service.update_profile(
        session, profile, name=body.name, description=body.description, camera=body.camera
    )
    return profile_read(updated)


@router.delete(
    "/camera-profiles/{profile_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(SURVEYOR)]
)
def delete_profile(profile_id: Id, session: SessionDep) -> None:
    """Remove a camera profile (vehicles given it keep their copy of its block)."""
    profile_service.delete_profile(session, profile_service.get_profile(session, profile_id))
