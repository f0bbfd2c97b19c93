"""The pose-graph back end of Semi-Supervised SLAM (paper III-A): odometry, loop closures, groundings.

Every mapping drive is an odometry chain of Pose2 frames; loop closures join any two frames of any drives
under a robust kernel (false closures from look-alike tunnels must not bend the map); groundings pin
frames to surveyed positions (position only, no heading). Frames are addressed by ``(chain, frame)``.
Poses are [x_m, y_m, yaw_rad] rows; ``wTi`` is frame i in the survey (world) frame, ``aTb`` frame b in
frame a. Before optimising, every drive is moved rigidly into the survey frame (:mod:`alignment`), then
Levenberg-Marquardt (or iSAM2 fed frame by frame) solves the graph. :class:`PoseGraphSession` keeps the
graph and re-solves warm-started from its last solution when only groundings change.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import gtsam
import numpy as np
from numpy.typing import NDArray

from driftmap.core.alignment import Anchor, FloatArray, dead_reckon, initial_guess
from driftmap.errors import BadInputError

FrameRef = tuple[int, int]
LoopKernel = Literal["none", "huber", "cauchy", "dcs", "geman_mcclure", "gnc_tls"]

_FREE_SIGMA_M = 1e3  # position sigma of a heading-only anchor, metres
_ESTIMATORS = {
    "huber": gtsam.noiseModel.mEstimator.Huber,
    "cauchy": gtsam.noiseModel.mEstimator.Cauchy,
    "dcs": gtsam.noiseModel.mEstimator.DCS,
    "geman_mcclure": gtsam.noiseModel.mEstimator.GemanMcClure,
}


@dataclass(frozen=True, eq=False)
class OdometryChain:
    """The odometry of one mapping drive.

    Attributes:
        iTj: (N-1, 3) step from frame i to j = i+1, frame j in frame i, [dx_m, dy_m, dtheta_rad].
        sigmas: (N-1, 3) or (3,) standard deviations of the steps [x_m, y_m, theta_rad].
        information: optional (N-1, 3, 3) full information matrices (x, y, theta order); overrides sigmas.
        wTi_init: optional (N, 3) initial poses already in the survey frame; else dead-reckoned and aligned.
    """

    iTj: FloatArray
    sigmas: FloatArray
    information: FloatArray | None = None
    wTi_init: FloatArray | None = None

    @property
    def num_frames(self) -> int:
        """Number of frames N of the drive."""
        return int(np.shape(self.iTj)[0]) + 1


@dataclass(frozen=True, eq=False)
class LoopClosure:
    """Frames a and b look like one place.

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
    information: FloatArray | None = None


@dataclass(frozen=True)
class Grounding:
    """A frame marked on the surveyed mine map (position only).

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
    solver: Literal["lm", "isam2"] = "lm"  # batch Levenberg-Marquardt, or iSAM2 (QR) fed frame by frame
    max_iterations: int = 100  # LM iterations; iSAM2: relinearisation rounds after the feed
    relative_error_tol: float = 1e-5  # stop when the error falls by less than this fraction
    absolute_error_tol: float = 1e-5  # or by less than this


ROBUST = PoseGraphParams()
PAPER = PoseGraphParams(loop_kernel="none")  # the paper's plain least squares
INCREMENTAL = PoseGraphParams(solver="isam2")  # escapes local minima that stop batch LM


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
        iterations: LM iterations, or iSAM2 updates; 0 for GNC (not reported by GTSAM).
        solve_time_s: wall time of the optimisation, seconds.
    """

    wTi: tuple[FloatArray, ...]
    closure_whitened_error: FloatArray
    closure_weight: FloatArray
    closure_accepted: NDArray[np.bool_]
    grounding_ids: tuple[int, ...]
    grounding_residual_m: FloatArray
    initial_error: float
    final_error: float
    iterations: int
    solve_time_s: float

    @property
    def closure_chi2(self) -> FloatArray:
        """(K,) squared Mahalanobis distance of each closure at the solution."""
        return np.asarray((self.closure_whitened_error**2).sum(axis=1), dtype=np.float64)

    def all_poses(self) -> FloatArray:
        """(sum N_c, 3) poses of all chains, chain after chain."""
        return np.concatenate(self.wTi) if self.wTi else np.zeros((0, 3))


def _fail(message: str, field: str) -> BadInputError:
    return BadInputError(message, field=field)


def _sigmas(values: object, count: int, field: str) -> FloatArray:
    s = np.array(values, dtype=np.float64)
    if s.shape == (3,):
        s = np.tile(s, (count, 1))
    if s.shape != (count, 3) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise _fail(f"sigmas must be ({count}, 3) or (3,), finite and positive", field)
    return s


def _noise_models(
    sigmas: FloatArray, information: FloatArray | None, params: PoseGraphParams, field: str
) -> list[gtsam.noiseModel.Base]:
    """Gaussian noise models with sigmas clamped to the minimum (information to the matching maximum)."""
    floor = np.array([params.min_sigma_m, params.min_sigma_m, params.min_sigma_rad])
    if information is None:
        return [gtsam.noiseModel.Diagonal.Sigmas(row) for row in np.maximum(sigmas, floor)]
    info = np.asarray(information, dtype=np.float64)
    if info.shape != (sigmas.shape[0], 3, 3) or not np.all(np.isfinite(info)):
        raise _fail(f"information must be ({sigmas.shape[0]}, 3, 3) and finite", field)
    scaled = floor[:, None] * info * floor[None, :]  # information in units of the floor
    w, V = np.linalg.eigh(0.5 * (scaled + scaled.transpose(0, 2, 1)))
    if np.any(w <= 0):
        raise _fail(
            f"information matrix {int(np.flatnonzero((w <= 0).any(axis=1))[0])} is not positive definite",
            field,
        )
    clamped = np.einsum("kij,kj,klj->kil", V, np.minimum(w, 1.0), V) / floor[:, None] / floor[None, :]
    return [gtsam.noiseModel.Gaussian.Information(m) for m in clamped]


class PoseGraphSession:
    """A pose graph that keeps its odometry and closures and re-solves after grounding edits.

    The first :meth:`solve` starts from the aligned dead-reckoning; later ones start from the previous
    solution (LM warm start) unless the gauge anchors changed, which reaches the same optimum faster.

    Args:
        chains: the drives' odometry, chain c has N_c frames.
        closures: loop closures between frames of any chains.
        groundings: initial groundings; they get ids 0..G-1.
        params: how to build and solve the graph.
    """

    def __init__(
        self,
        chains: Sequence[OdometryChain],
        closures: Sequence[LoopClosure],
        groundings: Sequence[Grounding] = (),
        params: PoseGraphParams = ROBUST,
    ) -> None:
        if params.loop_kernel not in (*_ESTIMATORS, "none", "gnc_tls"):
            raise _fail(f"unknown loop kernel {params.loop_kernel!r}", "loop_kernel")
        self.params = params
        self._sizes = [c.num_frames for c in chains]
        self._offsets = np.concatenate([[0], np.cumsum(self._sizes)]).astype(np.int64)
        self._graph = gtsam.NonlinearFactorGraph()
        self._dead_reckoned: list[FloatArray] = []
        self._dead_reckoned_steps: list[FloatArray] = []
        for c, chain in enumerate(chains):
            steps = np.asarray(chain.iTj, dtype=np.float64)
            if steps.ndim != 2 or steps.shape[1] != 3 or not np.all(np.isfinite(steps)):
                raise _fail("iTj must be (N-1, 3) and finite", f"chains[{c}].iTj")
            sigmas = _sigmas(chain.sigmas, steps.shape[0], f"chains[{c}].sigmas")
            self._dead_reckoned_steps.append(steps)
            for i, model in enumerate(
                _noise_models(sigmas, chain.information, params, f"chains[{c}].information")
            ):
                self._graph.add(
                    gtsam.BetweenFactorPose2(
                        self.key((c, i)), self.key((c, i + 1)), gtsam.Pose2(*steps[i]), model
                    )
                )
            init = chain.wTi_init
            if init is not None and (
                np.shape(init) != (steps.shape[0] + 1, 3) or not np.all(np.isfinite(init))
            ):
                raise _fail(f"wTi_init must be ({steps.shape[0] + 1}, 3) and finite", f"chains[{c}].wTi_init")
            self._dead_reckoned.append(
                dead_reckon(steps) if init is None else np.array(init, dtype=np.float64)
            )
        self._given = [c.wTi_init is not None for c in chains]
        self._first_closure = self._graph.size()
        self._closure_frames = np.zeros((len(closures), 4), dtype=np.int64)
        self._closure_aTb = np.zeros((len(closures), 3))
        self._closure_models = []
        for k, lc in enumerate(closures):
            field = f"closures[{k}]"
            self._closure_frames[k] = (
                *self._check_ref(lc.a, field + ".a"),
                *self._check_ref(lc.b, field + ".b"),
            )
            self._closure_aTb[k] = lc.aTb
            info = None if lc.information is None else np.asarray(lc.information)[None]
            base = _noise_models(
                _sigmas(lc.sigmas, 1, field + ".sigmas"), info, params, field + ".information"
            )[0]
            self._closure_models.append(base)
            if params.loop_kernel in _ESTIMATORS:
                kernel = _ESTIMATORS[params.loop_kernel].Create(params.kernel_width)
                model = gtsam.noiseModel.Robust.Create(kernel, base)
            else:
                model = base
            self._graph.add(
                gtsam.BetweenFactorPose2(self.key(lc.a), self.key(lc.b), gtsam.Pose2(*lc.aTb), model)
            )
        self._groundings: dict[int, Grounding] = {}
        for g in groundings:
            self.add_grounding(g)
        self._previous: gtsam.Values | None = None
        self._previous_gauge: list[tuple[int, int, bool]] | None = None

    def key(self, ref: FrameRef) -> int:
        """The GTSAM key of frame ``(chain, frame)``."""
        return int(self._offsets[ref[0]] + ref[1])

    def _check_ref(self, ref: FrameRef, field: str) -> FrameRef:
        c, i = int(ref[0]), int(ref[1])
        if not (0 <= c < len(self._sizes) and 0 <= i < self._sizes[c]):
            raise _fail(f"no frame {ref} (there are {len(self._sizes)} chains)", field)
        return c, i

    @property
    def groundings(self) -> dict[int, Grounding]:
        """The current groundings by id."""
        return dict(self._groundings)

    def add_grounding(self, grounding: Grounding) -> int:
        """Add a grounding and return its id."""
        gid = max(self._groundings, default=-1) + 1
        self._set(gid, grounding)
        return gid

    def move_grounding(
        self, grounding_id: int, xy_m: tuple[float, float], sigma_m: float | None = None
    ) -> None:
        """Give grounding ``grounding_id`` a new surveyed position (and optionally sigma), metres."""
        old = self._groundings[grounding_id]
        self._set(grounding_id, Grounding(old.frame, xy_m, old.sigma_m if sigma_m is None else sigma_m))

    def remove_grounding(self, grounding_id: int) -> None:
        """Drop grounding ``grounding_id``."""
        del self._groundings[grounding_id]

    def _set(self, gid: int, g: Grounding) -> None:
        field = f"groundings[{gid}]"
        frame = self._check_ref(g.frame, field + ".frame")
        xy = (float(g.xy_m[0]), float(g.xy_m[1]))
        if not (np.all(np.isfinite(xy)) and math.isfinite(g.sigma_m) and g.sigma_m > 0):
            raise _fail("position must be finite and sigma positive", field)
        self._groundings[gid] = Grounding(frame, xy, float(g.sigma_m))

    def solve(self) -> PoseGraphResult:
        """Optimise the graph with the current groundings; see :class:`PoseGraphResult`."""
        p = self.params
        ids = sorted(self._groundings)
        g_frames = np.array([self._groundings[i].frame for i in ids], dtype=np.int64).reshape(-1, 2)
        g_xy = np.array([self._groundings[i].xy_m for i in ids], dtype=np.float64).reshape(-1, 2)
        poses, anchors = initial_guess(
            self._dead_reckoned, self._given, self._closure_frames, self._closure_aTb, g_frames, g_xy,
            p.placement_inlier_m,
        )  # fmt: skip
        graph = gtsam.NonlinearFactorGraph(self._graph)
        for a in anchors:
            xy_sigma = _FREE_SIGMA_M if a.heading_only else p.anchor_sigma_m
            model = gtsam.noiseModel.Diagonal.Sigmas(np.array([xy_sigma, xy_sigma, p.anchor_sigma_rad]))
            graph.add(gtsam.PriorFactorPose2(self.key((a.chain, a.frame)), gtsam.Pose2(*a.wTi), model))
        for i in ids:
            g = self._groundings[i]
            model = gtsam.noiseModel.Isotropic.Sigma(2, max(g.sigma_m, p.min_sigma_m))
            graph.add(gtsam.PoseTranslationPrior2D(self.key(g.frame), np.array(g.xy_m), model))
        initial = gtsam.Values()
        for key, pose in enumerate(np.concatenate(poses) if poses else np.zeros((0, 3))):
            initial.insert(key, gtsam.Pose2(*pose))
        gauge = [(a.chain, a.frame, a.heading_only) for a in anchors]
        warm = self._previous is not None and gauge == self._previous_gauge
        start = self._previous if warm and self._previous is not None else initial
        t0 = time.perf_counter()
        if p.solver == "isam2" and not warm:
            values, iterations, weights = self._isam2(graph, initial, anchors), 0, None
        else:
            values, iterations, weights = self._batch(graph, start)
        elapsed = time.perf_counter() - t0
        self._previous, self._previous_gauge = values, gauge
        return self._result(graph, initial, values, iterations, weights, ids, g_xy, elapsed)

    def _batch(
        self, graph: gtsam.NonlinearFactorGraph, start: gtsam.Values
    ) -> tuple[gtsam.Values, int, FloatArray | None]:
        p = self.params
        lm = gtsam.LevenbergMarquardtParams()
        lm.setMaxIterations(p.max_iterations)
        lm.setRelativeErrorTol(p.relative_error_tol)
        lm.setAbsoluteErrorTol(p.absolute_error_tol)
        if p.loop_kernel != "gnc_tls":
            optimizer = gtsam.LevenbergMarquardtOptimizer(graph, start, lm)
            values = optimizer.optimize()
            return values, int(optimizer.iterations()), None
        gnc = gtsam.GncLMParams(lm)
        gnc.setLossType(gtsam.GncLossType.TLS)
        closures = range(self._first_closure, self._first_closure + len(self._closure_models))
        gnc.setKnownInliers([i for i in range(graph.size()) if i not in closures])
        optimizer = gtsam.GncLMOptimizer(graph, start, gnc)
        optimizer.setInlierCostThresholds(p.gnc_inlier_cost)
        values = optimizer.optimize()
        return values, 0, np.asarray(optimizer.getWeights(), dtype=np.float64)[closures.start : closures.stop]

    def _isam2(
        self, graph: gtsam.NonlinearFactorGraph, initial: gtsam.Values, anchors: list[Anchor]
    ) -> gtsam.Values:
        """Feed frames in key order to iSAM2 (QR), each chain's first frame held by a temporary prior."""
        p = self.params
        isam_params = gtsam.ISAM2Params()
        isam_params.setFactorization("QR")
        isam_params.relinearizeSkip = 1
        isam = gtsam.ISAM2(isam_params)
        due: list[list[tuple[object, bool]]] = [[] for _ in range(int(self._offsets[-1]))]
        for i in range(graph.size()):
            factor = graph.at(i)
            due[max(factor.keys())].append((factor, False))
        anchored = {self.key((a.chain, a.frame)) for a in anchors if not a.heading_only}
        model = gtsam.noiseModel.Diagonal.Sigmas(
            np.array([p.anchor_sigma_m, p.anchor_sigma_m, p.anchor_sigma_rad])
        )
        for start in self._offsets[:-1]:
            if int(start) not in anchored and int(start) < len(due):
                due[int(start)].append(
                    (gtsam.PriorFactorPose2(int(start), initial.atPose2(int(start)), model), True)
                )
        temporary: list[int] = []
        starts = set(self._offsets[:-1].tolist())
        for key, factors in enumerate(due):
            new, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
            for factor, _ in factors:
                new.add(factor)
            if key in starts:
                values.insert(key, initial.atPose2(key))
            else:  # dead-reckon from the current estimate of the previous frame
                c = int(np.searchsorted(self._offsets, key, side="right")) - 1
                step = gtsam.Pose2(*self._dead_reckoned_steps[c][key - int(self._offsets[c]) - 1])
                values.insert(key, isam.calculateEstimatePose2(key - 1).compose(step))
            indices = isam.update(new, values).getNewFactorsIndices()
            temporary += [int(ix) for ix, (_, temp) in zip(indices, factors, strict=True) if temp]
        isam.update(gtsam.NonlinearFactorGraph(), gtsam.Values(), temporary)
        error = graph.error(isam.calculateEstimate())
        for _ in range(p.max_iterations):
            isam.update()
            new_error = graph.error(isam.calculateEstimate())
            if error - new_error < max(p.absolute_error_tol, p.relative_error_tol * error):
                break
            error = new_error
        return isam.calculateEstimate()

    def _result(
        self,
        graph: gtsam.NonlinearFactorGraph,
        initial: gtsam.Values,
        values: gtsam.Values,
        iterations: int,
        weights: FloatArray | None,
        ids: list[int],
        g_xy: FloatArray,
        elapsed: float,
    ) -> PoseGraphResult:
        p = self.params
        poses = gtsam.utilities.extractPose2(values) if values.size() else np.zeros((0, 3))
        wTi = tuple(poses[a:b].copy() for a, b in zip(self._offsets[:-1], self._offsets[1:], strict=True))
        K = len(self._closure_models)
        whitened = np.zeros((K, 3))
        for k in range(K):
            error = graph.at(self._first_closure + k).unwhitenedError(values)
            whitened[k] = self._closure_models[k].whiten(error)
        norms = np.linalg.norm(whitened, axis=1)
        if weights is None:
            if p.loop_kernel in _ESTIMATORS:
                kernel = _ESTIMATORS[p.loop_kernel].Create(p.kernel_width)
                weights = np.array([kernel.weight(float(n)) for n in norms])
            else:
                weights = np.ones(K)
        keys = np.array([self.key(self._groundings[i].frame) for i in ids], dtype=np.int64)
        d = poses[keys, :2] - g_xy if len(ids) else np.zeros((0, 2))
        return PoseGraphResult(
            wTi=wTi,
            closure_whitened_error=whitened,
            closure_weight=weights,
            closure_accepted=norms**2 < p.accept_chi2,
            grounding_ids=tuple(ids),
            grounding_residual_m=np.column_stack([d, np.hypot(d[:, 0], d[:, 1])]),
            initial_error=float(graph.error(initial)),
            final_error=float(graph.error(values)),
            iterations=iterations,
            solve_time_s=elapsed,
        )


def optimise_pose_graph(
    chains: Sequence[OdometryChain],
    closures: Sequence[LoopClosure],
    groundings: Sequence[Grounding] = (),
    params: PoseGraphParams = ROBUST,
) -> PoseGraphResult:
    """Build and solve the pose graph of several drives; see :class:`PoseGraphSession` for the arguments."""
    return PoseGraphSession(chains, closures, groundings, params).solve()


def optimise_g2o_like(
    wTi_init: FloatArray,
    edge_ij: NDArray[np.int64],
    iTj: FloatArray,
    information: FloatArray,
    params: PoseGraphParams = ROBUST,
) -> PoseGraphResult:
    """Solve a benchmark graph (e.g. a g2o file) as odometry chains plus loop closures.

    The first edge i -> i+1 for every i is odometry; where none exists the chain breaks; every other
    edge is a loop closure under ``params.loop_kernel``. The first pose is held at its initial value.

    Args:
        wTi_init: (N, 3) initial poses, [x_m, y_m, yaw_rad].
        edge_ij: (K, 2) int pose indices (0..N-1) of each edge.
        iTj: (K, 3) measured pose of j in i.
        information: (K, 3, 3) information matrices (x, y, theta order).
        params: how to solve.

    Returns:
        The result; ``result.all_poses()`` is (N, 3) in pose order, closures in edge order minus odometry.
    """
    poses, edges = np.asarray(wTi_init, dtype=np.float64), np.asarray(edge_ij, dtype=np.int64)
    num = poses.shape[0]
    if poses.ndim != 2 or poses.shape[1] != 3 or edges.ndim != 2 or edges.shape[1] != 2:
        raise _fail("wTi_init must be (N, 3) and edge_ij (K, 2)", "edge_ij")
    if edges.size and (edges.min() < 0 or edges.max() >= num):
        raise _fail(f"edge indices must lie in 0..{num - 1}", "edge_ij")
    odometry = np.full(max(num - 1, 0), -1, dtype=np.int64)
    for k in np.flatnonzero(edges[:, 1] == edges[:, 0] + 1)[::-1]:
        odometry[edges[k, 0]] = k  # reversed, so the first edge of each pair wins
    starts = np.concatenate([[0], np.flatnonzero(odometry < 0) + 1, [num]])
    chain_of = np.searchsorted(starts, np.arange(num), side="right") - 1
    info = np.asarray(information, dtype=np.float64)
    chains = []
    for s, e in zip(starts[:-1], starts[1:], strict=True):
        rows = odometry[s : e - 1]
        sigmas = 1.0 / np.sqrt(np.abs(np.diagonal(info[rows], axis1=1, axis2=2)) + 1e-300)
        chains.append(OdometryChain(iTj[rows], sigmas.reshape(-1, 3), info[rows], poses[s:e]))
    used = np.zeros(edges.shape[0], dtype=bool)
    used[odometry[odometry >= 0]] = True
    closures = []
    for k in np.flatnonzero(~used):
        i, j = (int(v) for v in edges[k])
        a, b = (
            (int(chain_of[i]), i - int(starts[chain_of[i]])),
            (int(chain_of[j]), j - int(starts[chain_of[j]])),
        )
        sig = 1.0 / np.sqrt(np.abs(np.diag(info[k])) + 1e-300)
        closures.append(
            LoopClosure(
                a, b, (sig[0], sig[1], sig[2]), (iTj[k][0], iTj[k][1], iTj[k][2]), information=info[k]
            )
        )
    return optimise_pose_graph(chains, closures, (), params)
