"""Is a vehicle's camera obscured? Dust, water or a covered lens judged from its recent frames.

Three cheap measures per frame (a 320x240 frame takes about a millisecond or two):

* ``speckle``: the fraction of pixels more than ``speckle_jump_grey`` grey levels from the median of their
  3x3 neighbourhood. Aerosolised dust on the lens shows as isolated grey dots ([SSLAM], IV-A: 5-10 % of
  the pixels); a clean tunnel frame, even with sensor noise and motion blur, has almost none (< 0.1 %).
* per-cell sharpness: the mean absolute Laplacian of each ``cell_px`` square cell. A water drop blurs a fixed
  region of the lens, so the cells under it stay flat while the vehicle moves and the rest of the scene
  changes. Each cell keeps a decaying memory of its sharpest recent value (time constant ``memory_s``); a cell
  whose memory is below ``flat_ratio`` times the median cell's is persistently flat, and ``flat_area`` is
  the fraction of such cells. Clean drives keep every cell sharp at some moment within seconds.
* ``salient``: the SESAME salient fraction ``SS / SS_m`` ([SESAME] eq. 8-9) of the frame; a lens covered
  by mud or a cloth leaves a bland image with few salient patches. ``sharpness`` (variance of the
  Laplacian, grey levels squared) is reported with it.

``speckle``, ``salient`` and ``sharpness`` are smoothed by exponential moving averages of time constant
``smooth_s``.
The camera is judged obscured (reason ``dust``, ``water`` or ``covered``) once ``warmup_frames`` frames
have been seen and a smoothed measure passes its threshold. Thresholds were set on the simulator's dust 1/2
and water 1/2 copies of the tiny site of seed 3 against its clean drives, then checked on seed 11: no clean
frame of either site is flagged (0 of 2,841); after the warm-up every dust and water frame is, but for one
1.5 s gap in water 1 of seed 11 (3,113 of 3,128). A clean frame's persistently flat area was 0.0 on both
sites, water 1's about 0.5 % (threshold 0.3 %); a clean speckle fraction stays under 0.03 %, dust 1's over
1.6 % (threshold 1 %). About 1.6 ms a 320x240 frame, 0.4 ms when the salient fraction is given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.sesame.masks import SESAME_DEFAULT, SesameParams, frame_saliency
from driftmap.core.types import F32
from driftmap.errors import BadInputError

__all__ = [
    "OBSCURED_DEFAULT",
    "FrameMeasures",
    "ObscuredJudgement",
    "ObscuredParams",
    "ObscuredState",
    "frame_measures",
    "judge_obscured",
]

Reason = Literal["dust", "water", "covered"]


@dataclass(frozen=True)
class ObscuredParams:
    """Measures and thresholds of the obscured-camera judgement."""

    cell_px: int = 8  # side of the square cells of the local sharpness map, pixels
    speckle_jump_grey: int = 40  # a pixel this far from its 3x3 median is a speckle, grey levels
    speckle_max: float = 0.01  # smoothed speckle fraction above which the lens is dusty
    flat_ratio: float = 0.15  # a cell is flat when its sharpness memory is below this x the median cell's
    flat_area_max: float = 0.003  # fraction of persistently flat cells above which a drop is on the lens
    salient_min: float = 0.5  # smoothed salient fraction below which the lens is covered (S_th of SESAME)
    smooth_s: float = 1.0  # time constant of the moving averages of speckle, salient and sharpness, seconds
    memory_s: float = 3.0  # time constant of the cells' sharpness memory, seconds
    warmup_frames: int = 10  # frames seen before any judgement

    def __post_init__(self) -> None:
        if self.cell_px < 2 or min(self.smooth_s, self.memory_s) <= 0 or self.warmup_frames < 1:
            raise BadInputError(
                "need cell_px >= 2, smooth_s and memory_s > 0, warmup_frames >= 1", field="params"
            )


OBSCURED_DEFAULT = ObscuredParams()


@dataclass(frozen=True)
class FrameMeasures:
    """The measures of one frame."""

    salient: float  # SESAME salient fraction SS / SS_m, 0-1
    sharpness: float  # variance of the Laplacian, grey levels squared
    speckle: float  # fraction of isolated outlier pixels, 0-1
    cells: F32  # (rows, cols) mean absolute Laplacian of each cell, grey levels


def frame_measures(
    gray: NDArray[np.uint8],
    params: ObscuredParams = OBSCURED_DEFAULT,
    sesame: SesameParams = SESAME_DEFAULT,
    salient: float | None = None,
) -> FrameMeasures:
    """The measures of one ``(H, W)`` uint8 grey frame (at least two cells each way).

    Args:
        gray: the frame.
        params: cell size and speckle jump.
        sesame: mask parameters of the salient fraction.
        salient: the frame's salient fraction when already known (the live path takes it from the
            localiser's SESAME query mask, computed anyway); None computes it with ``sesame``.
    """
    if gray.dtype != np.uint8 or gray.ndim != 2 or min(gray.shape) < 2 * params.cell_px:
        raise BadInputError(f"need a (H, W) uint8 frame, got {gray.dtype} {gray.shape}", field="frame")
    lap = cv2.Laplacian(gray, cv2.CV_32F)
    speckle = float(
        np.mean(np.abs(gray.astype(np.int16) - cv2.medianBlur(gray, 3)) > params.speckle_jump_grey)
    )
    c = params.cell_px
    rows, cols = gray.shape[0] // c, gray.shape[1] // c
    # INTER_AREA over a whole number of pixels per cell is the cell mean
    cells = cv2.resize(np.abs(lap[: rows * c, : cols * c]), (cols, rows), interpolation=cv2.INTER_AREA)
    if salient is None:
        salient = float(frame_saliency(gray[None], sesame)[0][0])
    return FrameMeasures(salient, float(lap.var()), speckle, np.asarray(cells, dtype=np.float32))


@dataclass(frozen=True)
class ObscuredState:
    """What the judgement remembers of a vehicle's recent frames."""

    t_s: float | None = None  # time of the last frame, seconds
    frames: int = 0
    salient: float = 1.0  # smoothed salient fraction
    sharpness: float = 0.0  # smoothed Laplacian variance
    speckle: float = 0.0  # smoothed speckle fraction
    memory: F32 | None = None  # (rows, cols) decaying maximum of each cell's sharpness

    def to_arrays(self) -> dict[str, NDArray[np.generic]]:
        """Arrays for an ``.npz`` (see :meth:`from_arrays`)."""
        scalars = [
            math.nan if self.t_s is None else self.t_s,
            self.frames,
            self.salient,
            self.sharpness,
            self.speckle,
        ]
        out: dict[str, NDArray[np.generic]] = {"scalars": np.asarray(scalars, dtype=np.float64)}
        if self.memory is not None:
            out["memory"] = self.memory
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray[np.generic]]) -> ObscuredState:
        """The state saved by :meth:`to_arrays`."""
        t_s, frames, salient, sharpness, speckle = (float(v) for v in arrays["scalars"])
        memory = arrays.get("memory")
        return cls(
            None if math.isnan(t_s) else t_s,
            int(frames),
            salient,
            sharpness,
            speckle,
            None if memory is None else np.asarray(memory, dtype=np.float32),
        )


@dataclass(frozen=True)
class ObscuredJudgement:
    """The judgement after one frame, with the smoothed measures it rests on."""

    obscured: bool
    reason: Reason | None
    salient: float
    sharpness: float
    speckle: float
    flat_area: float  # fraction of persistently flat cells


def judge_obscured(
    state: ObscuredState, measures: FrameMeasures, t_s: float, params: ObscuredParams = OBSCURED_DEFAULT
) -> tuple[ObscuredState, ObscuredJudgement]:
    """Fold one frame's measures (time ``t_s``, seconds) into the state and judge the camera.

    A frame of another size than the remembered cells (a new camera) or an older time restarts the memory.
    """
    restart = (
        state.t_s is None
        or t_s <= state.t_s
        or state.memory is None
        or state.memory.shape != measures.cells.shape
    )
    if restart:
        alpha, memory, frames = 1.0, measures.cells, 1
    else:
        assert state.t_s is not None and state.memory is not None
        dt = t_s - state.t_s
        alpha = 1.0 - math.exp(-dt / params.smooth_s)
        memory = np.maximum(measures.cells, state.memory * math.exp(-dt / params.memory_s))
        frames = state.frames + 1

    def ema(old: float, new: float) -> float:
        return old + alpha * (new - old)

    new = ObscuredState(
        t_s,
        frames,
        ema(state.salient, measures.salient),
        ema(state.sharpness, measures.sharpness),
        ema(state.speckle, measures.speckle),
        memory.astype(np.float32),
    )
    reference = float(np.median(memory))
    flat_area = float(np.mean(memory < params.flat_ratio * reference)) if reference > 0 else 1.0
    reason: Reason | None = None
    if frames >= params.warmup_frames:
        if new.speckle > params.speckle_max:
            reason = "dust"
        elif new.salient < params.salient_min:
            reason = "covered"
        elif flat_area > params.flat_area_max:
            reason = "water"
    return new, ObscuredJudgement(
        reason is not None, reason, new.salient, new.sharpness, new.speckle, flat_area
    )
