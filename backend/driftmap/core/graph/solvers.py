"""The batch solvers of the pose graph: Levenberg-Marquardt, Powell's dog leg, and GNC-TLS over LM.

:func:`solve_batch` runs the solver of :attr:`PoseGraphParams.solver` on a built GTSAM graph:

- ``lm_dogleg`` (default): Levenberg-Marquardt; where it uses up ``max_iterations`` without converging,
  the dog leg continues from where it stopped, with as many iterations again. On a whole mine LM's damped
  steps can crawl for hundreds of iterations while the robust kernel takes closures back stretch by
  stretch, towards a minimum the dog leg reaches in tens; where LM converges, this is LM's solution.
- ``dogleg``: the dog leg alone (a trust region), LM where it meets an (almost) indeterminate system, which
  LM's damping copes with.
- ``lm``: LM alone. (``isam2`` feeds iSAM2 first, :class:`~driftmap.core.graph.posegraph.PoseGraphSession`,
  then polishes with LM.)

With the ``gnc_tls`` loop kernel every solver is GNC over LM (graduated non-convexity with a truncated
least-squares loss), which also returns each closure's weight.
"""

from __future__ import annotations

from typing import TypeVar

import gtsam
import numpy as np

from driftmap.core.graph.constraints import PoseGraphParams
from driftmap.core.types import F64

__all__ = ["solve_batch"]

_SolverParams = TypeVar("_SolverParams", gtsam.DoglegParams, gtsam.LevenbergMarquardtParams)


def solve_batch(
    graph: gtsam.NonlinearFactorGraph, start: gtsam.Values, params: PoseGraphParams, closures: range
) -> tuple[gtsam.Values, int, F64 | None]:
    """Solve ``graph`` from ``start`` with the batch solver of ``params``.

    Args:
        graph: the pose graph's factors.
        start: the initial estimate of every node.
        params: solver, loop kernel, iteration limit and error tolerances.
        closures: the factor indices of the loop closures (GNC's unknown inliers).

    Returns:
        The solution, the iterations taken (0 for GNC: GTSAM does not say), and for GNC the
        ``(len(closures),)`` closure weights in [0, 1] (else None).
    """
    if params.solver == "dogleg" and params.loop_kernel != "gnc_tls":
        solved = _dogleg(graph, start, params)
        if solved is not None:
            return *solved, None
    lm = _stopping(gtsam.LevenbergMarquardtParams(), params)
    if params.loop_kernel != "gnc_tls":
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, start, lm)
        values, iterations = optimizer.optimize(), int(optimizer.iterations())
        if params.solver == "lm_dogleg" and iterations >= params.max_iterations:  # stopped short
            solved = _dogleg(graph, values, params)
            if solved is not None:
                return solved[0], iterations + solved[1], None
        return values, iterations, None
    gnc = gtsam.GncLMParams(lm)
    gnc.setLossType(gtsam.GncLossType.TLS)
    gnc.setKnownInliers([i for i in range(graph.size()) if i not in closures])  # factor indices
    gnc_optimizer = gtsam.GncLMOptimizer(graph, start, gnc)
    gnc_optimizer.setInlierCostThresholds(params.gnc_inlier_cost)
    values = gnc_optimizer.optimize()
    weights = np.asarray(gnc_optimizer.getWeights(), dtype=np.float64)
    return values, 0, weights[closures.start : closures.stop]


def _dogleg(
    graph: gtsam.NonlinearFactorGraph, start: gtsam.Values, params: PoseGraphParams
) -> tuple[gtsam.Values, int] | None:
    """Powell's dog leg from ``start``: values and iterations, or None on an indeterminate system."""
    trust_region = gtsam.DoglegOptimizer(graph, start, _stopping(gtsam.DoglegParams(), params))
    try:
        return trust_region.optimize(), int(trust_region.iterations())
    except RuntimeError:  # an (almost) indeterminate system
        return None


def _stopping(solver: _SolverParams, params: PoseGraphParams) -> _SolverParams:
    """``solver`` with the iteration limit and error tolerances of ``params``."""
    solver.setMaxIterations(params.max_iterations)
    solver.setRelativeErrorTol(params.relative_error_tol)
    solver.setAbsoluteErrorTol(params.absolute_error_tol)
    return solver
