"""The pose graph's noise: per-step and per-closure information matrices (sigmas clamped to the floor of
:class:`~driftmap.core.graph.constraints.PoseGraphParams`) and the robust kernels the closures may use.

Information matrices are (K, 3, 3) over [x_m, y_m, theta_rad], GTSAM's Pose2 tangent order.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gtsam
import numpy as np

from driftmap.core.graph.constraints import LoopConstraint, PoseGraphParams
from driftmap.core.types import F64
from driftmap.errors import BadInputError

__all__ = ["ESTIMATORS", "check_sigmas", "closure_information", "fail", "information_matrices"]

_M = gtsam.noiseModel.mEstimator
ESTIMATORS: dict[str, Callable[[float], Any]] = {  # kernel name -> m-estimator factory
    "huber": _M.Huber.Create,
    "cauchy": _M.Cauchy.Create,
    "dcs": _M.DCS.Create,
    "geman_mcclure": _M.GemanMcClure.Create,
}


def fail(message: str, field: str) -> BadInputError:
    """The error of a bad graph input, naming its ``field``."""
    return BadInputError(message, field=field)


def check_sigmas(values: object, count: int, field: str) -> F64:
    """``values`` as (count, 3) standard deviations [x_m, y_m, theta_rad] (a (3,) row repeated), all finite
    and positive (BadInputError naming ``field`` otherwise)."""
    s = np.array(values, dtype=np.float64)
    if s.shape == (3,):
        s = np.tile(s, (count, 1))
    if s.shape != (count, 3) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise fail(f"sigmas must be ({count}, 3) or (3,), finite and positive", field)
    return s


def information_matrices(sigmas: F64, information: F64 | None, params: PoseGraphParams, field: str) -> F64:
    """(K, 3, 3) information matrices, sigmas clamped to the minimum (information to the matching maximum)."""
    floor = np.array([params.min_sigma_m, params.min_sigma_m, params.min_sigma_rad])
    if information is None:
        inverse = 1.0 / np.maximum(sigmas, floor) ** 2
        return np.asarray(np.einsum("ki,ij->kij", inverse, np.eye(3)), dtype=np.float64)
    info = np.asarray(information, dtype=np.float64)
    if info.shape != (sigmas.shape[0], 3, 3) or not np.all(np.isfinite(info)):
        raise fail(f"information must be ({sigmas.shape[0]}, 3, 3) and finite", field)
    scaled = floor[:, None] * info * floor[None, :]  # information in units of the floor
    w, V = np.linalg.eigh(0.5 * (scaled + scaled.transpose(0, 2, 1)))
    if np.any(w <= 0):
        raise fail(f"matrix {int(np.flatnonzero((w <= 0).any(axis=1))[0])} is not positive definite", field)
    clamped = np.einsum("kij,kj,klj->kil", V, np.minimum(w, 1.0), V) / floor[:, None] / floor[None, :]
    return np.asarray(clamped, dtype=np.float64)


def closure_information(closures: Sequence[LoopConstraint], params: PoseGraphParams) -> F64:
    """(K, 3, 3) information of each closure (its sigmas, or its matrix where given), clamped as
    :func:`information_matrices` does."""
    sigmas = [np.asarray(lc.sigmas, dtype=np.float64) for lc in closures]
    for k, s in enumerate(sigmas):
        if s.shape not in ((3,), (1, 3)) or not np.all(np.isfinite(s)) or np.any(s <= 0):
            raise fail("sigmas must be (1, 3) or (3,), finite and positive", f"closures[{k}].sigmas")
    stacked = np.array([s.reshape(3) for s in sigmas]).reshape(-1, 3)
    out = information_matrices(stacked, None, params, "closures")
    given = [k for k, lc in enumerate(closures) if lc.information is not None]
    for k in given:  # rare: checked and clamped one by one, naming the closure
        matrix = np.asarray(closures[k].information, dtype=np.float64)[None]
        out[k] = information_matrices(stacked[k : k + 1], matrix, params, f"closures[{k}].information")[0]
    return out
