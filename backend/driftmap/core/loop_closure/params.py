"""Parameters of the loop-closure search ([SSLAM] III-A-2, eq. 3), with their presets.

``LOOPS_PAPER`` is the paper's rule (the best earlier frame with d < d_t, no sequence or uniqueness test),
``LOOPS_DEFAULT`` what driftmap uses, ``LOOPS_FAST`` trades recall for speed. The module docstring of
:mod:`driftmap.core.loop_closure.search` explains the thresholds.
"""

from __future__ import annotations

from dataclasses import dataclass

from driftmap.core.imaging.params import SAD_DEFAULT, SAD_FAST, SadParams

__all__ = ["LOOPS_DEFAULT", "LOOPS_FAST", "LOOPS_PAPER", "LoopParams"]


@dataclass(frozen=True)
class LoopParams:
    """Loop closure by shifted SAD ([SSLAM] III-A-2, eq. 3) with candidates and sequence checks."""

    d_t: float | None = None  # absolute eq. 3 threshold on a sequence's mean d; None: from the background
    d_t_sigmas: float = 4.5  # relative d_t = background median - this x background sigma
    hit_sigmas: float = 3.0  # relative d_hit (a matching frame of a sequence), same form
    sigma_floor: float = 0.05  # background sigma used is at least this fraction of its median
    background_pairs: int = 2000  # random eligible pairs scored for the background median and sigma
    basis_keyframes: int = 20000  # descriptor axes and background from at most the first this many keyframes
    sad: SadParams = SAD_DEFAULT  # shift search +-x_max, +-y_max of eq. 3, pixels of the frames
    recent_frames: int = 20  # same-chain frames i-1 .. i-recent_frames are never compared with i
    recent_s: float = 0.0  # also exclude same-chain frames less than this many seconds older
    coarse_size_px: tuple[int, int] = (16, 8)  # (width, height) of the coarse thumbnail descriptor
    coarse_blur_px: float = 3.0  # Gaussian sigma before thumbnailing, frame pixels (shift tolerance)
    coarse_dims: int = 64  # PCA dimensions of the centred thumbnail; 0 keeps all
    coarse_seq_len: int = 5  # frames averaged along the diagonal of the coarse similarity
    top_k: int = 4  # distinct-place candidates per query by sequence-filtered descriptors, full SAD
    top_k_single: int = 4  # plus this many by single-frame descriptors (revisit starts, turns)
    nms_radius: int = 2  # a coarse candidate is the best within this many frames of its chain
    coarse_block: int = 256  # queries per descriptor matrix product; a search splits between blocks
    seq_len: int = 5  # query frames i-seq_len+1 .. i that must match a diagonal; 1 = single frame
    seq_min_hits: int = 4  # of those, frames that must have d < d_hit
    seq_slopes: tuple[float, ...] = (-1.5, -1, -0.67, 0.67, 1, 1.5)  # ref./query frames; < 0 reversing
    max_seq_checks: int = 3  # candidates per query with d < d_hit whose sequences are checked
    uniqueness_ratio: float = 0.7  # accept when other place's margin / this margin <= this; 1 = off
    same_place_frames: int = 4  # same-chain frames this close (or linked by a closure) are one place
    track: bool = True  # continuing the previous frame's closure needs no uniqueness test
    max_closures_per_query: int = 2  # closures emitted per query frame (to distinct places)
    sigma_xy_m: float = 2.0  # suggested position sigma of a confident closure, metres
    sigma_xy_max_m: float = 6.0  # ... of a closure at the limits of the tests, metres
    sigma_theta_rad: float = 0.2  # suggested heading sigma (same-direction passes), radians
    seed: int = 0  # of the background pair sample

    def __post_init__(self) -> None:
        if self.d_t is not None and not self.d_t > 0:
            raise ValueError(f"LoopParams.d_t must be > 0 or None, got {self.d_t}")
        nonneg = (
            "recent_frames",
            "recent_s",
            "coarse_dims",
            "nms_radius",
            "same_place_frames",
            "top_k_single",
        )
        for name in nonneg:
            if getattr(self, name) < 0:
                raise ValueError(f"LoopParams.{name} must be >= 0, got {getattr(self, name)}")
        for name in (
            "top_k",
            "seq_len",
            "coarse_seq_len",
            "max_seq_checks",
            "max_closures_per_query",
            "coarse_block",
            "basis_keyframes",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"LoopParams.{name} must be >= 1, got {getattr(self, name)}")
        if not 1 <= self.seq_min_hits <= self.seq_len:
            raise ValueError("LoopParams.seq_min_hits must be in 1 .. seq_len")
        if not self.seq_slopes or 0 in self.seq_slopes:
            raise ValueError("LoopParams.seq_slopes must be non-empty and non-zero")
        if not 0 < self.uniqueness_ratio <= 1 or self.background_pairs < 10:
            raise ValueError("LoopParams: 0 < uniqueness_ratio <= 1 and background_pairs >= 10")
        if min(self.coarse_size_px) <= 0 or not 0 < self.sigma_xy_m <= self.sigma_xy_max_m:
            raise ValueError("LoopParams: coarse_size_px > 0 and 0 < sigma_xy_m <= sigma_xy_max_m")


LOOPS_DEFAULT = LoopParams()
# The paper's rule: the best earlier frame with d < d_t, no sequence or uniqueness test (aliasing-prone).
LOOPS_PAPER = LoopParams(
    coarse_seq_len=1,
    top_k=8,
    seq_len=1,
    seq_min_hits=1,
    uniqueness_ratio=1.0,
    track=False,
    max_closures_per_query=1,
)
LOOPS_FAST = LoopParams(
    sad=SAD_FAST, coarse_dims=32, top_k=3, top_k_single=2, max_seq_checks=2, background_pairs=500
)
