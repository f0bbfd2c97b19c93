"""Parameter sets of the synthetic mine: site sizes, the camera rig, vehicle motion and rendering.

All are frozen dataclasses with one comment per field. Units are in the names (``_m``, ``_s``,
``_rad``, ``_px``). A site size bundles the layout and the frame budget; :data:`SIZES` names them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "RIGS",
    "RIG_DEFAULT",
    "RIG_WIDE180",
    "SIZES",
    "VEHICLE_DEFAULT",
    "CameraRigParams",
    "LayoutParams",
    "SiteSize",
    "VehicleParams",
    "camera_rig",
    "site_size",
]


@dataclass(frozen=True)
class LayoutParams:
    """Shape of a ladder-style extraction level: a perimeter loop, cross-cut production tunnels, spurs."""

    loop_length_m: float  # length of the perimeter loop along its long axis
    loop_depth_m: float  # length of the loop's short sides (and of each production cross-cut)
    rungs: int  # production cross-cuts between the two long sides (0: drawpoints sit on the loop)
    drawpoint_spacing_m: float = 18.0  # spacing of drawpoints along a production tunnel
    drawpoint_length_m: float = 13.0  # length of a drawpoint side drive, junction to face
    dump_length_m: float = 14.0  # length of the dump (tip) spur
    access_length_m: float = 30.0  # length of the access drive spur ending in a ventilation door
    drive_width_m: float = 5.8  # width of perimeter drives and access
    production_width_m: float = 5.4  # width of production tunnels
    drawpoint_width_m: float = 5.0  # width of drawpoints and the dump spur
    height_m: float = 5.0  # floor-to-roof height everywhere
    bend_m: float = 1.5  # amplitude of the gentle lateral bends of long tunnels


@dataclass(frozen=True)
class SiteSize:
    """A named site size: its layout and its total frame budget (mapping + localisation)."""

    name: str  # "tiny", "small", "medium", "large" or "mine"
    layout: LayoutParams  # geometry of the level
    frame_budget: int  # rendered frames in all drives (obscured copies are extra)
    localisation_drives: int  # number of localisation drives sharing what the mapping leaves
    min_localisation_frames: int  # localisation frames guaranteed even if mapping eats the budget


# Centreline length and frames (seeds vary them a little): tiny ~105 m / ~1,400 frames (mapping alone
# takes most of it), small ~370 m / ~4,500, medium ~1.46 km / ~15,000, large ~5.7 km / ~62,000, mine ~20 km (a producing mine's worth of drives and cross-cuts) / ~220,000. Every
# mapping drive leaves from the dump, so mapping takes about three quarters of the frames.
SIZES: dict[str, SiteSize] = {
    "tiny": SiteSize("tiny", LayoutParams(24.0, 15.0, 0, access_length_m=0.0), 400, 1, 100),
    "small": SiteSize("small", LayoutParams(88.0, 44.0, 1, access_length_m=22.0), 4500, 2, 500),
    "medium": SiteSize("medium", LayoutParams(330.0, 100.0, 3, access_length_m=90.0), 15000, 4, 2400),
    "large": SiteSize(
        "large",
        LayoutParams(1300.0, 190.0, 9, drawpoint_spacing_m=28.0, access_length_m=150.0),
        60000,
        8,
        9000,
    ),
    "mine": SiteSize(
        "mine",
        LayoutParams(3100.0, 420.0, 20, drawpoint_spacing_m=28.0, access_length_m=200.0),
        220000,
        12,
        20000,
    ),
}


def site_size(name: str) -> SiteSize:
    """The :class:`SiteSize` called ``name``.

    Raises:
        ValueError: an unknown size name.
    """
    try:
        return SIZES[name]
    except KeyError:
        raise ValueError(f"unknown site size {name!r}; choose one of {', '.join(SIZES)}") from None


@dataclass(frozen=True)
class CameraRigParams:
    """The camera on the vehicle, its lens and its mounting (see :mod:`driftmap.sim.rig`)."""

    width_px: int = 320  # frame width
    height_px: int = 240  # frame height
    focal_px: float = 150.0  # focal length (square pixels); 320 px wide gives ~94 deg horizontal FOV
    height_m: float = 2.2  # camera centre above the floor
    pitch_rad: float = math.radians(20.0)  # optical axis below the horizontal
    y_c_m: float = 1.0  # rear axle to camera along the way the camera looks (paper eq. 1), metres
    facing: str = "front"  # "front": looks ahead of the vehicle; "rear": mounted at the back, looks behind
    lens: str = "pinhole"  # "pinhole" (ideal, no distortion) or "fisheye" (OpenCV equidistant model)
    distortion: tuple[float, ...] = ()  # fisheye k1..k4 (OpenCV); () for the ideal pinhole
    max_angle_rad: float = math.pi / 2  # fisheye: rays further than this off the optical axis are black
    roi_height_px: int = 92  # rows of the ground ROI, ending roi_bottom_margin_px above the bottom
    roi_bottom_margin_px: int = 4  # rows left out at the bottom of the frame
    tunnel_width_m: float = 5.0  # narrowest tunnel the ROI must see only floor in
    max_offset_m: float = 0.5  # lateral offset of the camera from the centreline covered by the ROI
    max_yaw_dev_rad: float = math.radians(6.0)  # heading deviation from the tunnel axis covered by the ROI


RIG_DEFAULT = CameraRigParams()

_WIDE180_DISTORTION = (0.012, -0.003, 0.0005, 0.0)  # a real 180-degree lens departs a little from f * theta


def _focal_for_half_width(half_width_px: float, half_angle_rad: float, k: tuple[float, ...]) -> float:
    """Fisheye focal length putting a ray ``half_angle_rad`` off axis at ``half_width_px`` from the centre."""
    t = half_angle_rad
    return half_width_px / (t * (1 + sum(c * t ** (2 * i + 2) for i, c in enumerate(k))))


# The camera of paper 000: 944x800 monochrome, 180 degrees across the width, on the back of an LHD,
# looking behind it and down at the floor.
RIG_WIDE180 = CameraRigParams(
    width_px=944,
    height_px=800,
    focal_px=_focal_for_half_width(471.5, math.pi / 2, _WIDE180_DISTORTION),
    height_m=2.0,
    pitch_rad=math.radians(25.0),
    y_c_m=1.6,
    facing="rear",
    lens="fisheye",
    distortion=_WIDE180_DISTORTION,
    roi_height_px=208,
    roi_bottom_margin_px=168,
)
RIGS: dict[str, CameraRigParams] = {"pinhole": RIG_DEFAULT, "wide180": RIG_WIDE180}


def camera_rig(name: str) -> CameraRigParams:
    """The rig called ``name`` in :data:`RIGS`.

    Raises:
        ValueError: an unknown camera name.
    """
    try:
        return RIGS[name]
    except KeyError:
        raise ValueError(f"unknown camera {name!r}; choose one of {', '.join(RIGS)}") from None


@dataclass(frozen=True)
class VehicleParams:
    """Speeds, accelerations and noise of the simulated load-haul-dump vehicle."""

    fps: float = 10.0  # frames per second of every drive
    mapping_speed_mps: float = 7.0  # cruise speed while mapping
    empty_speed_mps: float = 7.0  # cruise speed of an empty LHD (dump -> drawpoint)
    loaded_speed_mps: float = 5.0  # cruise speed of a loaded LHD (drawpoint -> dump)
    reverse_speed_mps: float = 3.0  # cruise speed when reversing out of a dead end
    accel_mps2: float = 1.0  # acceleration limit
    decel_mps2: float = 1.5  # braking limit
    lateral_accel_mps2: float = 1.5  # limits speed in bends: v <= sqrt(a / curvature)
    turn_radius_m: float = 5.0  # corners of the rear-axle path are arcs of this radius (less if cramped)
    path_smoothing_m: float = 1.0  # Gaussian sigma softening the curvature steps of those arcs
    wander_m: float = 0.3  # amplitude of the lateral wander about the centreline
    wander_wavelength_m: tuple[float, float] = (18.0, 45.0)  # range of wander wavelengths
    heading_noise_rad: float = math.radians(0.6)  # amplitude of the smooth heading (crab) noise
    deadend_standoff_m: float = 5.5  # camera stops this far from a dead-end face
    reverse_into_m: float = 7.0  # how far the rear swings into the next tunnel when reversing out
    grounding_sigma_m: float = 0.3  # standard deviation of surveyed grounding positions
    stop_s: float = 1.2  # dwell at a grounding stop
    dig_s: tuple[float, float] = (1.0, 1.8)  # range of one bucket-fill pause at a drawpoint
    dig_strokes: int = 2  # back-and-forth strokes while digging (localisation drives)
    mapping_dig_strokes: int = 1  # strokes at each drawpoint of a mapping drive
    dig_stroke_m: float = 0.8  # length of one digging stroke
    tip_s: float = 5.0  # dwell at the dump
    wait_probability: float = 0.25  # chance of a traffic wait at a junction during localisation
    wait_s: tuple[float, float] = (2.0, 5.0)  # range of a traffic wait
    turn_max_rad: float = math.radians(125.0)  # sharpest heading change allowed at a junction


VEHICLE_DEFAULT = VehicleParams()
