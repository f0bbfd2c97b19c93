"""Parameters of the ground-plane visual odometry, with their presets.

``ODOMETRY_PAPER`` is the linear model of [SSLAM] (eq. 1-2), ``ODOMETRY_DEFAULT`` what driftmap uses
(bird's-eye when the camera allows it), ``ODOMETRY_FAST`` trades accuracy for speed and ``ODOMETRY_LIVE``
is a localising vehicle's per-frame step. Units are in the field names (``_px``, ``_m``, ``_rad``) or
comments.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

__all__ = [
    "ODOMETRY_DEFAULT",
    "ODOMETRY_FAST",
    "ODOMETRY_LIVE",
    "ODOMETRY_PAPER",
    "OdometryModel",
    "OdometryParams",
]

OdometryModel = Literal["auto", "linear", "homography"]


@dataclass(frozen=True)
class OdometryParams:
    """Ground-plane visual odometry ([SSLAM] eq. 1, 2; bird's-eye extension)."""

    model: OdometryModel = "auto"  # "linear": eq. 1-2 with k_x/k_y; "homography": bird's-eye; auto picks
    max_step_m: float = 1.5  # largest forward or reverse travel per frame that is searched, metres
    max_turn_rad: float = 0.12  # largest heading change per frame that is searched, radians
    max_lateral_m: float = 0.3  # sideways slip searched on top of what a turn explains, metres
    bev_res_m: float = 0.02  # bird's-eye grid cell, metres (coarsened when the grid would exceed bev_max_px)
    bev_max_px: int = 640  # largest side of the bird's-eye grid, cells
    max_roi_px: int = 480  # linear model: the ROI window is down-sampled so its longer side is at most this
    patch_px: int = 8  # patch-normalisation square on every pyramid level, pixels
    coarse_min_px: int = 10  # the coarsest pyramid level keeps at least this many pixels across the ROI
    coarse_candidates: int = 3  # local minima of the coarse exhaustive search refined to full resolution
    refine_radius_px: int = 2  # search radius around the up-sampled estimate on each finer level
    rerotate: bool = True  # bird's-eye: re-match with the current grid rotated by the estimated turn
    motion_prior: bool = (
        True  # bird's-eye drives: also descend from the previous step's shift; lower cost wins
    )
    linear_blur_px: float = (
        3.0  # linear model: Gaussian blur before matching (fine grain decorrelates under zoom)
    )
    linear_patches: tuple[int, int] = (
        3,
        3,
    )  # linear model: ROI split into (cols, rows) tracked patches, median
    self_calibrate: bool = True  # dead_reckon, bird's-eye: estimate the homography's horizon offset
    horizon_max_px: float = 40.0  # largest horizon offset searched by the self-calibration, pixels
    calibrate_lever: bool = True  # self-calibration also fits the rotation centre y_c to the floor's turns
    lever_max_gain_se: float = 0.025  # ... kept when its standard error moves the turn gain less than this
    pitch_window_m: float = 12.0  # horizon tracked over this window of travel (Gaussian sd, m); 0: one median
    pitch_gate_z: float = 3.0  # ... applied where it departs from the median by this many standard errors
    subpixel: Literal["lk", "parabola"] = "lk"  # sub-pixel: Gauss-Newton on the SSD, or per-axis SAD parabola
    stationary_px: float = 0.3  # |shift| below this (pixels of the matching grid) with a good match -> zero
    stationary_min_confidence: float = 0.3  # the "good match" of stationary detection
    texture_ref: float = 4.0  # high-pass intensity std (grey levels) giving texture factor 1 - 1/e
    blur_ref: float = 0.12  # re-blur gradient loss at which the blur factor reaches 1 (sharp enough)
    distinct_ref: float = 0.25  # 1 - best/second-best cost at which the match factor reaches 1
    saturated_low: int = 5  # grey level at or below which a pixel is black-clipped
    saturated_high: int = 250  # grey level at or above which a pixel is white-clipped
    flat_std: float = 1.0  # local 5x5 intensity std (grey levels) below which a pixel counts as flat
    sigma_xy_base_m: float = 0.01  # position sigma of a perfect step, metres
    sigma_xy_per_m: float = 0.03  # plus this fraction of the step length
    sigma_theta_base_rad: float = 0.002  # heading sigma of a perfect step, radians
    sigma_theta_per_m: float = 0.004  # plus this many radians per metre travelled
    confidence_floor: float = 0.05  # sigmas are divided by max(confidence, this)

    def __post_init__(self) -> None:
        if self.model not in ("auto", "linear", "homography"):
            raise ValueError(f"OdometryParams.model must be auto, linear or homography, got {self.model!r}")
        positive = {
            "max_step_m": self.max_step_m,
            "bev_res_m": self.bev_res_m,
            "texture_ref": self.texture_ref,
            "blur_ref": self.blur_ref,
            "distinct_ref": self.distinct_ref,
            "confidence_floor": self.confidence_floor,
        }
        for name, value in positive.items():
            if not value > 0:
                raise ValueError(f"OdometryParams.{name} must be > 0, got {value}")
        if self.max_turn_rad < 0 or self.max_lateral_m < 0:
            raise ValueError("OdometryParams: max_turn_rad and max_lateral_m must be >= 0")
        if not self.lever_max_gain_se > 0:
            raise ValueError(f"OdometryParams.lever_max_gain_se must be > 0, got {self.lever_max_gain_se}")
        if self.pitch_window_m < 0 or self.pitch_gate_z < 0:
            raise ValueError("OdometryParams: pitch_window_m and pitch_gate_z must be >= 0")
        if min(self.linear_patches) < 1 or self.horizon_max_px <= 0:
            raise ValueError("OdometryParams: linear_patches >= (1, 1) and horizon_max_px > 0")
        if self.patch_px < 2 or self.coarse_min_px < 2 or self.coarse_candidates < 1:
            raise ValueError("OdometryParams: patch_px >= 2, coarse_min_px >= 2, coarse_candidates >= 1")
        if self.refine_radius_px < 1 or self.bev_max_px < 64 or self.max_roi_px < 16:
            raise ValueError("OdometryParams: refine_radius_px >= 1, bev_max_px >= 64, max_roi_px >= 16")
        if self.subpixel not in ("lk", "parabola", "equiangular"):
            raise ValueError(
                f"OdometryParams.subpixel must be lk, parabola or equiangular, got {self.subpixel!r}"
            )


ODOMETRY_DEFAULT = OdometryParams()
ODOMETRY_PAPER = OdometryParams(model="linear")
ODOMETRY_FAST = OdometryParams(bev_res_m=0.04, max_roi_px=240, coarse_candidates=1, rerotate=False)
#: a localising vehicle's per-frame step (driftmap.core.localisation.motion): FAST without the second descent
#: from the previous step's shift, parabola sub-pixel; on the simulated small site's loc-01 (400 frames, one
#: core) about 1/10 of FAST's time per step for a step-length error within 0.1 cm of the default's (bench:
#: bench/bench_localise.py prints the odometry part of a live frame)
ODOMETRY_LIVE = dataclasses.replace(ODOMETRY_FAST, motion_prior=False, subpixel="parabola")
