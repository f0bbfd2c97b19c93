"""What the pose graph is made of: drives' odometry, loop closures, groundings; its parameters and result.

Frames are addressed by ``(chain, frame)``. Poses are [x_m, y_m, yaw_rad] rows; ``wTi`` is frame i in the
survey (world) frame, ``aTb`` frame b in frame a. :mod:`driftmap.core.graph.posegraph` builds and solves
the graph from these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import NDArray

from driftmap.core.types import F64

__all__ = [
    "POSEGRAPH_DEFAULT",
    "POSEGRAPH_INCREMENTAL",
    "POSEGRAPH_PAPER",
    "FrameRef",
    "GroundingConstraint",
    "LoopConstraint",
    "LoopKernel",
    "OdometryChain",
    "PoseGraphParams",
    "PoseGraphResult",
    "PoseGraphSolver",
]

FrameRef = tuple[int, int]
LoopKernel = Literal["none", "huber", "cauchy", "dcs", "geman_mcclure", "gnc_tls"]
# Batch solvers: "lm_dogleg" is Levenberg-Marquardt, continued by Powell's dog leg (a trust region) from
# where LM stopped when LM used up max_iterations without converging; "lm" and "dogleg" are each alone;
# "isam2" feeds iSAM2 (QR) frame by frame and polishes with Levenberg-Marquardt.
PoseGraphSolver = Literal["lm_dogleg", "lm", "dogleg", "isam2"]


@dataclass(frozen=True, eq=False)
class OdometryChain:
    """The odometry of one mapping drive.

    Attributes:
        iTj: (N-1, 3) step from frame i to j = i+1, frame j in frame i, [dx_m, dy_m, dtheta_rad].
        sigmas: (N-1, 3) or (3,) standard deviations of the steps [x_m, y_m, theta_rad].
        information: optional (N-1, 3, 3) full information matrices (x, y, theta order); overrides sigmas.
        wTi_init: optional (N, 3) initial poses already in the survey frame; else dead-reckoned and aligned.
    """

    iTj: F64
    sigmas: F64
    information: F64 | None = None
    wTi_init: F64 | None = None

    @property
    def num_frames(self) -> int:
        """Number of frames N of the drive."""
        return int(np.shape(self.iTj)[0]) + 1


@dataclass(frozen=True, eq=False)
class LoopConstraint:
    """A loop-closure edge of the graph: frames a and b look like one place.

    Attributes:
        a: (chain, frame) of the first frame.
        b: (chain, frame) of the second frame.
        sigmas: standard deviations of the measurement [x_m, y_m, theta_rad].
        aTb: measured pose of b in a, [x_m, y_m, yaw_rad]; identity when the frames look the same.
        sad: the SAD score d(i, j) that proposed the closure (paper eq. 3), for reports only.
        information: optional (3, 3) full information matrix; overrides sigmas.
    """

    a: FrameRef
    b: FrameRef
    sigmas: tuple[float, float, float]
    aTb: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sad: float = math.nan
    information: F64 | None = None


@dataclass(frozen=True)
class GroundingConstraint:
    """A grounding's prior in the graph: a frame marked on the surveyed mine map (position only).

    Attributes:
        frame: (chain, frame) that was at the marked spot.
        xy_m: surveyed position, survey frame, metres.
        sigma_m: standard deviation of the marking in x and y, metres.
    """

    frame: FrameRef
    xy_m: tuple[float, float]
    sigma_m: float = 0.5


@dataclass(frozen=True)
class PoseGraphParams:
    """How the pose graph is built and solved."""

    loop_kernel: LoopKernel = "dcs"  # robust kernel on loop closures
    kernel_width: float = 1.0  # DCS Phi, or Huber/Cauchy/Geman-McClure width, whitened units
    gnc_inlier_cost: float = 0.5  # gnc_tls: largest cost (chi2 / 2) of an inlier closure
    accept_chi2: float = 11.34  # a closure is accepted when its final chi2 (3 dof) is below (99 %)
    min_sigma_m: float = 1e-3  # position sigmas are clamped up to this before GTSAM, metres
    min_sigma_rad: float = 1e-4  # heading sigmas are clamped up to this, radians
    anchor_sigma_m: float = 1.0  # weak prior on a group of drives nothing ties to the survey, metres
    anchor_sigma_rad: float = 0.1  # its heading sigma, also for groundings that fix no rotation, radians
    placement_inlier_m: float = 5.0  # closures agreeing within this place a drive before optimising, m
    align_min_baseline_m: float = 5.0  # groundings spanning less do not rotate a drive before optimising, m
    node_spacing_m: float = 5.0  # travel between graph nodes where no constraint needs one, m (0: all)
    node_max_steps: int = 50  # most odometry steps between two graph nodes
    solver: PoseGraphSolver = "lm_dogleg"  # see PoseGraphSolver
    last_solver: PoseGraphSolver = "dogleg"  # a calibrated build's last solve, cold from the placement
    max_iterations: int = 100  # iterations of the batch solver (also of the polish after iSAM2)
    relative_error_tol: float = 1e-5  # stop when the error falls by less than this fraction
    absolute_error_tol: float = 1e-5  # or by less than this

    def __post_init__(self) -> None:
        if self.loop_kernel not in get_args(LoopKernel):
            raise ValueError(f"PoseGraphParams: unknown loop_kernel {self.loop_kernel!r}")
        for solver in (self.solver, self.last_solver):
            if solver not in get_args(PoseGraphSolver):
                raise ValueError(f"PoseGraphParams: unknown solver {solver!r}")
        if min(self.min_sigma_m, self.min_sigma_rad, self.anchor_sigma_m, self.anchor_sigma_rad) <= 0:
            raise ValueError("PoseGraphParams: sigmas must be positive")
        if self.node_spacing_m < 0 or self.node_max_steps < 1:
            raise ValueError("PoseGraphParams: node_spacing_m must be >= 0 and node_max_steps >= 1")
        if self.max_iterations < 1 or self.kernel_width <= 0:
            raise ValueError("PoseGraphParams: max_iterations and kernel_width must be positive")


POSEGRAPH_DEFAULT = PoseGraphParams()  # DCS on closures: false closures do not bend the map
POSEGRAPH_PAPER = PoseGraphParams(loop_kernel="none")  # the paper's plain least squares
POSEGRAPH_INCREMENTAL = PoseGraphParams(solver="isam2")  # escapes local minima that stop batch LM


@dataclass(frozen=True, eq=False)
class PoseGraphResult:
    """The optimised map.

    Attributes:
        wTi: per chain, (N_c, 3) optimised poses in the survey frame, [x_m, y_m, yaw_rad].
        closure_whitened_error: (K, 3) final error of each closure whitened by its Gaussian noise.
        closure_weight: (K,) final weight of each closure after the robust kernel (1 = full).
        closure_accepted: (K,) bool, final chi2 below ``accept_chi2``.
        grounding_ids: (G,) ids of the groundings, in the row order of ``grounding_residual_m``.
        grounding_residual_m: (G, 3) [dx, dy, distance], optimised position minus surveyed, metres.
        initial_error: graph error (sum of factor costs) at the initial guess.
        final_error: graph error at the solution.
        iterations: the batch solver's iterations (after the feed for solver isam2; LM's and the dog leg's
            together for lm_dogleg); 0 for GNC (GTSAM does not say).
        solve_time_s: wall time of the optimisation, seconds.
        num_nodes: poses the optimiser solved (frames kept as nodes, see ``node_spacing_m``).
    """

    wTi: tuple[F64, ...]
    closure_whitened_error: F64
    closure_weight: F64
    closure_accepted: NDArray[np.bool_]
    grounding_ids: tuple[int, ...]
    grounding_residual_m: F64
    initial_error: float
    final_error: float
    iterations: int
    solve_time_s: float
    num_nodes: int = 0

    @property
    def closure_chi2(self) -> F64:
        """(K,) squared Mahalanobis distance of each closure at the solution."""
        return np.asarray((self.closure_whitened_error**2).sum(axis=1), dtype=np.float64)

    def all_poses(self) -> F64:
        """(sum N_c, 3) poses of all chains, chain after chain."""
        return np.concatenate(self.wTi) if self.wTi else np.zeros((0, 3))
