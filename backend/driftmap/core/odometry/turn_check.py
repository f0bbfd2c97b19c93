"""A camera's mounting checked against a short drive that turns: which way the camera looks, which way the
floor turns, and the point the vehicle turns about (the lever ``y_c``).

The vehicle drives ahead (or in reverse) and turns through a roughly known angle, e.g. round a junction of
the mine. Dead reckoning with the camera's calibration (self-calibrating, as every drive does) then tells:

- ``forward_sign``: the travel summed along the path must come out forward (backward on a drive in reverse);
- the turn's direction: the heading change must have the sign of the turn driven. Floor points measured to
  the camera's right instead of its left mirror the ground plane, and every turn then comes out the wrong way;
  a mirrored calibration cannot be mended by a factor: the ground plane must be fitted again;
- the lever ``y_c`` (rear axle to camera, metres), two ways. The floor's own rotation between the near and far
  parts of the ground region, against the arc model, says where the vehicle turns about
  (:mod:`driftmap.core.odometry.rotation_centre`), with a standard error, whatever the turn's angle; a ground
  region too short for that (a wide lens's, whose floor region spans ~2 m against a ~5 m lever arm) leaves it
  undetermined. And the lever with which odometry turns through exactly the stated angle: every step's turn
  is its floor motion across over its lever arm, so the drive's total turn falls as the lever grows, and the
  one lever that matches the stated angle is found by bisection (bird's-eye model; the steps are re-solved,
  not matched again). Its accuracy is the stated angle's: 5 degrees off a 90-degree junction moves it by about
  6 % of the lever arm, a full circle in a yard by under 2 %.

The self-calibrated lever is preferred when determined (odometry uses it on such drives anyway); else the
stated turn's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import MatchedSteps, reckon
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, OdometryParams
from driftmap.core.odometry.rotation_centre import LEVER_SEARCH_M
from driftmap.core.odometry.scale_check import MIN_TRAVEL_M
from driftmap.core.odometry.step import OdometryStep
from driftmap.errors import BadInputError

__all__ = ["MIN_TURN_RAD", "TurnCheck", "check_turn", "lever_for_turn", "mount_camera"]

MIN_TURN_RAD = math.radians(20.0)  # a stated turn below this is too small to check a direction or a lever
LEVER_SAMPLES = 41  # levers tried across the search range before the bisection
LEVER_TOL_M = 0.005  # the bisection stops this close to the lever that turns through the stated angle


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
        fitted_y_c_m: the lever the floor's own rotation determines, metres; None when it does not.
        fitted_se_m: its standard error, metres; None with ``fitted_y_c_m``.
        turn_y_c_m: the lever with which odometry turns through the stated angle, metres; None without the
            bird's-eye model, or when no lever within 5 m of the configured one does.
    """

    travelled_m: float
    turned_rad: float
    stated_rad: float
    sign_wrong: bool
    direction_wrong: bool
    configured_y_c_m: float
    fitted_y_c_m: float | None
    fitted_se_m: float | None
    turn_y_c_m: float | None = None

    @property
    def y_c_m(self) -> float:
        """The lever the check finds: the fitted one, else the stated turn's, else the configured one."""
        for lever in (self.fitted_y_c_m, self.turn_y_c_m):
            if lever is not None:
                return lever
        return self.configured_y_c_m

    @property
    def turn_ratio(self) -> float:
        """Odometry's turn over the stated one (1 when they agree; negative when the direction is wrong)."""
        return self.turned_rad / self.stated_rad


def check_turn(
    matched: MatchedSteps,
    camera: CameraModel,
    stated_rad: float,
    params: OdometryParams = ODOMETRY_DEFAULT,
    *,
    reverse: bool = False,
) -> TurnCheck:
    """Compare a drive that turns, dead-reckoned with ``camera``, with the turn driven.

    Args:
        matched: the drive's steps (:func:`~driftmap.core.odometry.drive.match_frames` with ``camera``).
        camera: the camera checked.
        stated_rad: the turn driven, radians, + left (counter-clockwise seen from above); at least 20 degrees.
        params: odometry parameters (as the steps were matched with).
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
    run = reckon(matched, camera, params)
    travelled = float(sum(step.prev_T_curr[0] for step in run.steps))
    if abs(travelled) < MIN_TRAVEL_M:
        raise BadInputError(
            f"odometry travelled only {travelled:.3f} m: the drive shows no usable motion", field="drive"
        )
    turned = _turned(run.steps)
    if abs(turned) < 0.5 * MIN_TURN_RAD:
        raise BadInputError(
            f"odometry turned only {math.degrees(turned):.1f} degrees: the drive shows no usable turn",
            field="drive",
        )
    fitted = run.lever_se_m is not None
    direction_wrong = bool(np.sign(turned) != np.sign(stated_rad))
    return TurnCheck(
        travelled_m=travelled,
        turned_rad=turned,
        stated_rad=float(stated_rad),
        sign_wrong=(travelled < 0) != reverse,
        direction_wrong=direction_wrong,
        configured_y_c_m=float(camera.y_c_m),
        fitted_y_c_m=float(run.lever_m) if fitted else None,
        fitted_se_m=run.lever_se_m,
        turn_y_c_m=None if direction_wrong else lever_for_turn(matched, camera, stated_rad, params),
    )


def _turned(steps: list[OdometryStep]) -> float:
    """The heading change over ``steps``, radians (+ left)."""
    return float(sum(step.prev_T_curr[2] for step in steps))


def lever_for_turn(
    matched: MatchedSteps, camera: CameraModel, stated_rad: float, params: OdometryParams = ODOMETRY_DEFAULT
) -> float | None:
    """The lever ``y_c`` (metres) with which the drive's dead reckoning turns through ``stated_rad``.

    The steps are re-solved with each lever tried (the lever's self-calibration off, the horizon's on), over
    ``configured +- 5 m``; the total turn's magnitude falls as the lever grows, and the longest-lever bracket
    where it crosses the stated one is bisected to :data:`LEVER_TOL_M` (levers whose arms come near zero make
    turns of any size, and are not the vehicle's). None without the bird's-eye model with
    self-calibration (its steps cannot be re-solved), or when no lever in the range turns that far.
    """
    if not (params.self_calibrate and camera.homography() is not None and matched.steps):
        return None
    if matched.steps[0].model != "homography":
        return None
    fixed = dataclasses.replace(params, calibrate_lever=False)

    def excess(lever: float) -> float:
        turned = _turned(reckon(matched, dataclasses.replace(camera, y_c_m=lever), fixed).steps)
        return abs(turned) - abs(stated_rad)

    levers = np.linspace(camera.y_c_m - LEVER_SEARCH_M, camera.y_c_m + LEVER_SEARCH_M, LEVER_SAMPLES)
    values = [excess(float(y)) for y in levers]
    for k in reversed(range(LEVER_SAMPLES - 1)):  # from long lever arms down, to stop before any near zero
        if np.isfinite(values[k]) and np.isfinite(values[k + 1]) and values[k] >= 0 > values[k + 1]:
            lo, hi = float(levers[k]), float(levers[k + 1])
            while hi - lo > LEVER_TOL_M:
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if excess(mid) >= 0 else (lo, mid)
            return 0.5 * (lo + hi)
    return None


def mount_camera(camera: CameraModel, check: TurnCheck) -> CameraModel:
    """The camera with the mounting the check found: its lever (:attr:`TurnCheck.y_c_m`) and ``forward_sign``
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
    sign = -camera.forward_sign if check.sign_wrong else camera.forward_sign
    return dataclasses.replace(camera, y_c_m=check.y_c_m, forward_sign=sign)
