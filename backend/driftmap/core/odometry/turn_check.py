"""A camera's mounting checked against a short drive that turns: which way the camera looks, which way the
floor turns, and the point the vehicle turns about (the lever ``y_c``).

The vehicle drives ahead (or in reverse) and turns through a roughly known angle, e.g. round a junction of
the mine. Dead reckoning with the camera's calibration (self-calibrating, as every drive does) then tells:

- ``forward_sign``: the travel summed along the path must come out forward (backward on a drive in reverse);
- the turn's direction: the heading change must have the sign of the turn driven. Floor points measured to
  the camera's right instead of its left mirror the ground plane, and every turn then comes out the wrong way;
  a mirrored calibration cannot be mended by a factor: the ground plane must be fitted again;
- the lever ``y_c`` (rear axle to camera, metres): the floor's own rotation between the near and far parts of
  the ground region, against the arc model, says where the vehicle turns about
  (:mod:`driftmap.core.odometry.rotation_centre`), with a standard error. A drive whose turns do not
  determine it well enough leaves it unknown; a straight drive never does.

The stated angle need not be exact: the ratio of odometry's turn to it is reported, not judged.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import DeadReckoning
from driftmap.core.odometry.scale_check import MIN_TRAVEL_M
from driftmap.errors import BadInputError

__all__ = ["MIN_TURN_RAD", "TurnCheck", "check_turn", "mount_camera"]

MIN_TURN_RAD = math.radians(20.0)  # a stated turn below this is too small to check a direction or a lever


@dataclass(frozen=True)
class TurnCheck:
    """The outcome of a turn check.

    Attributes:
        travelled_m: odometry's travel summed along the path, metres (+ forward in the vehicle's frame).
        turned_rad: odometry's heading change over the drive, radians (+ counter-clockwise: a left turn).
        stated_rad: the turn driven, radians (+ left), as the user gave it.
        sign_wrong: the travel has the opposite sign to the drive's: flip ``forward_sign``.
        direction_wrong: the heading change has the opposite sign to the turn driven: the ground plane is
            mirrored (fit it again).
        configured_y_c_m: the camera's lever, metres.
        fitted_y_c_m: the lever the drive's turns determine, metres; None when they do not.
        fitted_se_m: its standard error, metres; None with ``fitted_y_c_m``.
    """

    travelled_m: float
    turned_rad: float
    stated_rad: float
    sign_wrong: bool
    direction_wrong: bool
    configured_y_c_m: float
    fitted_y_c_m: float | None
    fitted_se_m: float | None

    @property
    def turn_ratio(self) -> float:
        """Odometry's turn over the stated one (1 when they agree; negative when the direction is wrong)."""
        return self.turned_rad / self.stated_rad


def check_turn(
    run: DeadReckoning, configured_y_c_m: float, stated_rad: float, *, reverse: bool = False
) -> TurnCheck:
    """Compare a dead-reckoned drive that turns with the turn driven.

    Args:
        run: the drive's dead reckoning (:func:`~driftmap.core.odometry.drive.dead_reckon`, self-calibrating).
        configured_y_c_m: the camera's lever ``y_c``, metres.
        stated_rad: the turn driven, radians, + left (counter-clockwise seen from above); at least 20 degrees.
        reverse: the drive was in reverse.

    Raises:
        BadInputError: a stated turn that is not finite or under 20 degrees (field ``turn_deg``), or a drive
            whose odometry shows under 5 cm of travel or under half the 20 degrees of turn (field ``drive``).
    """
    if not (math.isfinite(stated_rad) and abs(stated_rad) >= MIN_TURN_RAD):
        raise BadInputError(
            f"must be a turn of at least {math.degrees(MIN_TURN_RAD):.0f} degrees, found "
            f"{math.degrees(stated_rad):.1f}",
            field="turn_deg",
        )
    travelled = float(sum(step.prev_T_curr[0] for step in run.steps))
    if abs(travelled) < MIN_TRAVEL_M:
        raise BadInputError(
            f"odometry travelled only {travelled:.3f} m: the drive shows no usable motion", field="drive"
        )
    turned = float(sum(step.prev_T_curr[2] for step in run.steps))
    if abs(turned) < 0.5 * MIN_TURN_RAD:
        raise BadInputError(
            f"odometry turned only {math.degrees(turned):.1f} degrees: the drive shows no usable turn",
            field="drive",
        )
    fitted = run.lever_se_m is not None
    return TurnCheck(
        travelled_m=travelled,
        turned_rad=turned,
        stated_rad=float(stated_rad),
        sign_wrong=(travelled < 0) != reverse,
        direction_wrong=bool(np.sign(turned) != np.sign(stated_rad)),
        configured_y_c_m=float(configured_y_c_m),
        fitted_y_c_m=float(run.lever_m) if fitted else None,
        fitted_se_m=run.lever_se_m,
    )


def mount_camera(camera: CameraModel, check: TurnCheck) -> CameraModel:
    """The camera with the mounting the check found: the fitted lever (when determined) and ``forward_sign``
    flipped when the travel came out backwards.

    Raises:
        BadInputError: the turn came out the wrong way (a mirrored ground plane is not mended here; field
            ``turn_deg``).
    """
    if check.direction_wrong:
        raise BadInputError(
            f"odometry turned {math.degrees(check.turned_rad):+.0f} degrees for a turn of "
            f"{math.degrees(check.stated_rad):+.0f} (+ left): the ground plane is mirrored; fit it again with "
            "floor y measured to the camera's left",
            field="turn_deg",
        )
    y_c = check.fitted_y_c_m if check.fitted_y_c_m is not None else camera.y_c_m
    sign = -camera.forward_sign if check.sign_wrong else camera.forward_sign
    return dataclasses.replace(camera, y_c_m=y_c, forward_sign=sign)
