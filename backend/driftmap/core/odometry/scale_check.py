"""A camera's floor scale and mounting direction checked against a drive over a measured straight distance.

The vehicle drives straight ahead over a distance measured on the floor (tape, survey marks). Dead reckoning
with the camera's calibration gives the travel along the starting heading; their ratio is the factor by
which every floor length of the calibration is off (``k_x``, ``k_y``, ``y_h`` and the homography's floor
side), and travel that comes out backwards on a forward drive means ``forward_sign`` is wrong.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.camera import CameraModel
from driftmap.errors import BadInputError

__all__ = ["ScaleCheck", "check_scale", "scale_camera"]

MIN_TRAVEL_M = 0.05  # odometry travel below this says nothing about the scale


@dataclass(frozen=True)
class ScaleCheck:
    """The outcome of a scale check.

    Attributes:
        travelled_m: odometry's signed travel along the starting heading, metres (+ forward).
        measured_m: the measured distance, metres (> 0), driven forward (or in reverse, see ``reverse``).
        ratio: ``measured_m / |travelled_m|``: multiply the calibration's floor lengths by this.
        sign_wrong: odometry's travel has the opposite sign to the drive's: flip ``forward_sign``.
    """

    travelled_m: float
    measured_m: float
    ratio: float
    sign_wrong: bool


def check_scale(wTi: NDArray, measured_m: float, *, reverse: bool = False) -> ScaleCheck:
    """Compare dead-reckoned travel with a measured straight distance.

    Args:
        wTi: ``(N, 3)`` dead-reckoned poses ``[x_m, y_m, yaw_rad]`` of the drive, N >= 2.
        measured_m: the distance driven, metres, > 0.
        reverse: the drive was in reverse (odometry should report negative travel).

    Raises:
        BadInputError: a bad pose array, a non-positive distance, or odometry travel below 5 cm.
    """
    poses = np.asarray(wTi, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or len(poses) < 2:
        raise BadInputError(f"need (N >= 2, 3) poses, got shape {poses.shape}", field="wTi")
    if not (math.isfinite(measured_m) and measured_m > 0):
        raise BadInputError(f"must be a positive distance, found {measured_m}", field="distance_m")
    yaw0 = float(poses[0, 2])
    travelled = float((poses[-1, :2] - poses[0, :2]) @ np.array([math.cos(yaw0), math.sin(yaw0)]))
    if abs(travelled) < MIN_TRAVEL_M:
        raise BadInputError(
            f"odometry travelled only {travelled:.3f} m: the drive shows no usable motion", field="drive"
        )
    return ScaleCheck(
        travelled, float(measured_m), float(measured_m) / abs(travelled), (travelled < 0) != reverse
    )


def scale_camera(camera: CameraModel, ratio: float, *, flip_sign: bool = False) -> CameraModel:
    """The camera with every floor length multiplied by ``ratio`` (and ``forward_sign`` flipped if asked).

    ``k_x``, ``k_y``, ``y_h`` and the floor side of ``ground_homography`` scale; ``y_c`` (measured on the
    vehicle), the ROI and the lens do not.
    """
    if not (math.isfinite(ratio) and ratio > 0):
        raise BadInputError(f"must be positive, found {ratio}", field="ratio")
    hom = camera.homography()
    scaled = None
    if hom is not None:
        h = np.diag([ratio, ratio, 1.0]) @ hom
        scaled = tuple((float(r[0]), float(r[1]), float(r[2])) for r in h)
    return dataclasses.replace(
        camera,
        k_x_m_per_px=camera.k_x_m_per_px * ratio,
        k_y_m_per_px=camera.k_y_m_per_px * ratio,
        y_h_m=camera.y_h_m * ratio,
        ground_homography=scaled,
        forward_sign=-camera.forward_sign if flip_sign else camera.forward_sign,
    )
