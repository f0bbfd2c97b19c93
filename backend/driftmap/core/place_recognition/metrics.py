"""Place-recognition metrics: recall@1, the precision-recall sweep, its area, recall at 100 % precision.

Every query gets one best match with a confidence score. Sweeping a threshold over the scores ([SSLAM]
section V: X_thresh), a query counts as *matched* when its score is at or above the threshold; a matched
query is a true positive when its match is acceptable (ground truth), else a false positive. As in [SSLAM]:

* precision = true positives / matched queries,
* recall = true positives / recallable queries (queries with at least one acceptable match).

The curve has one point per distinct score, from the highest down (tied scores enter together, so the
order of tied queries cannot flatter the curve). The area under it (AUC) is the step-wise sum of recall
gain times precision (average precision, no interpolation between points); recall at 100 % precision is the largest recall of a point whose
precision is exactly 1 (0 when the most confident match is already wrong).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.types import F64, BoolArr
from driftmap.errors import BadInputError

__all__ = [
    "PlaceMetrics",
    "PrCurve",
    "Reliability",
    "evaluate_matches",
    "fit_calibration",
    "match_correct",
    "pr_curve",
    "reliability",
]


@dataclass(frozen=True, eq=False)
class PrCurve:
    """A precision-recall sweep.

    Attributes:
        thresholds: ``(K,)`` float64 distinct scores, descending; point k matches every score >= it.
        precision: ``(K,)`` float64 in [0, 1].
        recall: ``(K,)`` float64 in [0, 1], non-decreasing.
    """

    thresholds: F64
    precision: F64
    recall: F64

    @property
    def auc(self) -> float:
        """Area under the curve: sum over points of recall gain x precision, in [0, 1]."""
        if self.recall.size == 0:
            return 0.0
        return float(np.sum(np.diff(np.r_[0.0, self.recall]) * self.precision))

    @property
    def recall_at_full_precision(self) -> float:
        """Largest recall with precision exactly 1; 0 when there is none."""
        perfect = self.precision >= 1.0
        return float(self.recall[perfect].max()) if perfect.any() else 0.0


@dataclass(frozen=True)
class PlaceMetrics:
    """Summary figures of one place-recognition run.

    Attributes:
        recall_at_1: fraction of recallable queries whose best match is acceptable.
        auc: area under the precision-recall curve.
        recall_at_full_precision: recall at 100 % precision.
        queries: number of queries.
        recallable: number of queries with at least one acceptable match.
    """

    recall_at_1: float
    auc: float
    recall_at_full_precision: float
    queries: int
    recallable: int


def match_correct(best: NDArray[np.integer], gt: BoolArr) -> BoolArr:
    """Whether each query's best match is acceptable.

    Args:
        best: ``(Q,)`` integer index of each query's best reference.
        gt: ``(Q, D)`` bool, True where reference j is acceptable for query i.

    Returns:
        ``(Q,)`` bool.
    """
    best = np.asarray(best)
    gt = np.asarray(gt, dtype=bool)
    if gt.ndim != 2 or best.shape != (gt.shape[0],):
        raise BadInputError(f"need best (Q,) and gt (Q, D), got {best.shape}, {gt.shape}", field="best")
    if best.size and (best.min() < 0 or best.max() >= gt.shape[1]):
        raise BadInputError(f"best indices must lie in [0, {gt.shape[1]})", field="best")
    return np.asarray(gt[np.arange(gt.shape[0]), best], dtype=bool)


def pr_curve(score: F64, correct: BoolArr, recallable: int) -> PrCurve:
    """Precision-recall sweep over the scores.

    Args:
        score: ``(Q,)`` confidence of each query's match, higher = more confident (non-finite: never matched).
        correct: ``(Q,)`` bool, the match is acceptable.
        recallable: number of queries that have an acceptable match (the recall denominator), > 0.

    Returns:
        :class:`PrCurve` with one point per distinct finite score.
    """
    score = np.asarray(score, dtype=np.float64)
    correct = np.asarray(correct, dtype=bool)
    if score.ndim != 1 or correct.shape != score.shape:
        raise BadInputError(f"need score and correct of one shape (Q,), got {score.shape}", field="score")
    if recallable <= 0:
        raise BadInputError("no query has an acceptable match", field="recallable")
    finite = np.isfinite(score)
    s, c = score[finite], correct[finite]
    order = np.argsort(-s, kind="stable")
    s, c = s[order], c[order]
    tp = np.cumsum(c)
    last = np.r_[np.flatnonzero(s[1:] != s[:-1]), s.size - 1]  # the last query of each tie group
    matched = last + 1
    return PrCurve(
        thresholds=s[last].astype(np.float64),
        precision=tp[last] / matched,
        recall=tp[last] / float(recallable),
    )


def evaluate_matches(best: NDArray[np.integer], score: F64, gt: BoolArr) -> tuple[PlaceMetrics, PrCurve]:
    """Recall@1, AUC and recall at 100 % precision of best matches against a ground-truth table.

    Args:
        best: ``(Q,)`` index of each query's best reference.
        score: ``(Q,)`` its confidence, higher = more confident.
        gt: ``(Q, D)`` bool acceptable pairs.

    Returns:
        ``(metrics, curve)``.
    """
    correct = match_correct(best, gt)
    has_gt = np.asarray(gt, dtype=bool).any(axis=1)
    recallable = int(has_gt.sum())
    curve = pr_curve(score, correct, recallable)
    metrics = PlaceMetrics(
        recall_at_1=float(correct[has_gt].sum()) / recallable,
        auc=curve.auc,
        recall_at_full_precision=curve.recall_at_full_precision,
        queries=int(correct.size),
        recallable=recallable,
    )
    return metrics, curve


@dataclass(frozen=True)
class Reliability:
    """A reliability diagram: frames binned by reported confidence, and how many of each bin were right.

    Attributes:
        edges: (B + 1,) float64 bin edges over [0, 1].
        mean_confidence: (B,) float64 mean reported confidence per bin (NaN when empty).
        right_share: (B,) float64 share of the bin's frames that were right (NaN when empty).
        counts: (B,) int64 frames per bin.
    """

    edges: F64
    mean_confidence: F64
    right_share: F64
    counts: NDArray[np.int64]

    @property
    def expected_calibration_error(self) -> float:
        """Frame-weighted mean |right share - mean confidence| over the bins (0: perfectly calibrated)."""
        ok = self.counts > 0
        if not ok.any():
            return float("nan")
        gap = np.abs(self.right_share[ok] - self.mean_confidence[ok])
        return float(np.sum(gap * self.counts[ok]) / self.counts[ok].sum())


def reliability(confidence: F64, right: BoolArr, bins: int = 10) -> Reliability:
    """The reliability diagram of (N,) reported ``confidence`` in [0, 1] against (N,) ``right``; NaN
    confidences (lost frames) are left out."""
    c = np.asarray(confidence, dtype=np.float64)
    r = np.asarray(right, dtype=bool)
    if c.shape != r.shape or c.ndim != 1:
        raise ValueError(f"confidence and right must be (N,), got {c.shape} and {r.shape}")
    keep = np.isfinite(c)
    c, r = np.clip(c[keep], 0.0, 1.0), r[keep]
    edges = np.linspace(0.0, 1.0, bins + 1)
    which = np.minimum(np.searchsorted(edges, c, side="right") - 1, bins - 1)
    counts = np.bincount(which, minlength=bins).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_c = np.bincount(which, weights=c, minlength=bins) / counts
        share = np.bincount(which, weights=r.astype(np.float64), minlength=bins) / counts
    return Reliability(edges, mean_c, share, counts)


def fit_calibration(
    raw: F64, right: BoolArr, knots: int = 21, keep_raw: float = 0.05
) -> tuple[tuple[float, float], ...]:
    """Calibration of a raw score in [0, 1] by logistic (Platt) scaling on its logit:
    ``P(right) = sigmoid(a + b logit(raw))``, fitted by maximum likelihood on (N,) ``raw`` and ``right``
    (NaN raw values are left out) and read off at ``knots`` evenly spaced raw values as
    (raw, probability) points for :func:`driftmap.core.localisation.hmm.calibrated`.

    An increasing map keeps the ranking of the raw score, so thresholds move but recall at a precision does
    not; an isotonic fit would tie frames its flat stretches join. Where right and wrong frames separate
    well the fitted sigmoid saturates at 1 and would tie the top frames too, so ``keep_raw`` of the raw score
    is blended in: ``(1 - keep_raw) P + keep_raw raw`` is strictly increasing and never claims certainty.
    The first knot is pinned to 0: a frame whose views tell nothing apart (raw 0: a covered lens, a blank
    wall) is given no confidence, whatever share of such frames happened to be right in the fitting data.
    Raw values are clipped to [0.005, 0.995] before the logit.
    """
    x = np.asarray(raw, dtype=np.float64)
    y = np.asarray(right, dtype=np.float64)
    keep = np.isfinite(x)
    x, y = np.clip(x[keep], 0.005, 0.995), y[keep]
    if x.size == 0 or y.min() == y.max():
        raise ValueError("a calibration needs finite raw scores of both right and wrong frames")
    features = np.column_stack([np.ones_like(x), np.log(x / (1.0 - x))])
    w = np.zeros(2)
    for _ in range(50):  # Newton-Raphson on the log-likelihood, lightly regularised
        p = 1.0 / (1.0 + np.exp(-features @ w))
        grad = features.T @ (y - p) - 1e-6 * w
        hess = (features * (p * (1.0 - p))[:, None]).T @ features + 1e-6 * np.eye(2)
        step = np.linalg.solve(hess, grad)
        w += step
        if float(np.abs(step).max()) < 1e-9:
            break
    w[1] = max(w[1], 1e-3)  # keep it increasing
    grid = np.linspace(0.0, 1.0, knots)
    g = np.clip(grid, 0.005, 0.995)
    values = 1.0 / (1.0 + np.exp(-(w[0] + w[1] * np.log(g / (1.0 - g)))))
    values[0], values[-1] = min(values[0], values[1]), max(values[-1], values[-2])
    values = (1.0 - keep_raw) * values + keep_raw * grid
    values[0] = 0.0
    return tuple((float(a_), float(v)) for a_, v in zip(grid, values, strict=True))
