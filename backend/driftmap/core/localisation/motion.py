"""The vehicle's own motion between localisation frames: ground-plane odometry ([SSLAM] III-A-1, eq. 1-2).

A localising vehicle carries the camera its map was built from. :class:`OdometryFeed` runs the mapping
pipeline's single odometry step (:func:`driftmap.core.odometry.step.match_step` on frames prepared once with
:func:`driftmap.core.odometry.grid.prepare_frame`, the same implementation, with a cheaper preset) on each pair of
consecutive frames and says whether the step can be trusted. The localiser uses a usable step twice: to move
its belief by the distance actually driven (:mod:`driftmap.core.localisation.hmm`, odometry-gated transitions) and to
dead-reckon its continuous position (:mod:`driftmap.core.localisation.track`).

A step is *unusable* (the localiser falls back to the speed bound of eq. 9-10 for that frame) when there is
no camera, the frame is not a raw grey frame of the camera's size, the gap to the previous frame is longer
than ``max_gap_s`` (dropped frames: the floor has moved out of the search range), or the step's own
confidence (texture, blur, occlusion, match distinctiveness) is below ``min_confidence`` (dust or water on
the lens, motion blur).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.grid import GridFrame, MatchGrid, match_grid, prepare_frame
from driftmap.core.odometry.params import ODOMETRY_LIVE, OdometryParams
from driftmap.core.odometry.step import OdometryStep, match_step

__all__ = ["MotionParams", "OdometryFeed"]


@dataclass(frozen=True)
class MotionParams:
    """When a localisation frame's odometry step is trusted."""

    min_confidence: float = 0.3  # a step whose OdometryStep.confidence is below this is unusable
    max_gap_s: float = 0.35  # frames further apart than this are not matched (dropped frames)


MOTION_DEFAULT = MotionParams()


class OdometryFeed:
    """Odometry steps between a vehicle's consecutive frames, each frame prepared once.

    Args:
        camera: the vehicle's calibrated camera (size, ground ROI, k_x, k_y, y_c, y_h, homography).
        params: odometry parameters (default :data:`~driftmap.core.odometry.params.ODOMETRY_LIVE`, the mapping
            pipeline's step made cheap enough for every live frame); self-calibration, which needs a whole
            drive, is not applied to single steps.
        motion: when a step is trusted.
    """

    def __init__(
        self,
        camera: CameraModel,
        params: OdometryParams = ODOMETRY_LIVE,
        motion: MotionParams = MOTION_DEFAULT,
    ) -> None:
        self.camera = camera
        self.params = params
        self.motion = motion
        self._setup: MatchGrid = match_grid(camera, params)
        self._prev: GridFrame | None = None
        self._prev_t_s = float("nan")
        self._prior_px: tuple[float, float] | None = None

    def accepts(self, frame: NDArray[np.generic]) -> bool:
        """True for a raw grey uint8 frame of the camera's (H, W)."""
        return frame.dtype == np.uint8 and frame.shape == (self.camera.height_px, self.camera.width_px)

    def previous_frame(self) -> NDArray[np.uint8]:
        """(H, W) uint8 the last frame fed, or (0, 0) before the first (kept in the localiser's state)."""
        return np.zeros((0, 0), dtype=np.uint8) if self._prev is None else self._prev.recorded_frame()

    def restore(self, frame: NDArray[np.uint8], t_s: float) -> None:
        """Continue after ``frame`` taken at ``t_s`` (from a stored state; an empty frame forgets it)."""
        self._prev, self._prior_px = None, None
        self._prev_t_s = float(t_s)
        if frame.size and self.accepts(frame):
            self._prev = prepare_frame(frame, self.camera, self._setup, self.params)

    def step(self, frame: NDArray[np.generic], t_s: float) -> OdometryStep | None:
        """The usable step from the previous frame to ``frame`` taken at ``t_s`` seconds, or None.

        Args:
            frame: (H, W) uint8 grey frame of the camera's size (anything else: None, and forgotten).
            t_s: its timestamp, seconds.

        Returns:
            The :class:`OdometryStep` (``dx_m`` signed metres, ``dtheta_rad`` counter-clockwise) when usable
            (see the module docstring), else None.
        """
        if not self.accepts(frame):
            self._prev, self._prior_px = None, None
            return None
        curr = prepare_frame(np.asarray(frame, dtype=np.uint8), self.camera, self._setup, self.params)
        prev, gap_s = self._prev, t_s - self._prev_t_s
        self._prev, self._prev_t_s = curr, float(t_s)
        if prev is None or not (0.0 < gap_s <= self.motion.max_gap_s):
            self._prior_px = None
            return None
        step, _pairs = match_step(prev, curr, self.camera, self._setup, self.params, self._prior_px)
        self._prior_px = step.shift_px
        if step.confidence < self.motion.min_confidence:
            return None
        return step
