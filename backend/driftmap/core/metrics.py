"""Place-recognition metrics: recall@1, the precision-recall sweep, its area, recall at 100 % precision.

Every query gets one best match with a confidence score. Sweeping a threshold over the scores (paper 000
section V: X_thresh), a query counts as *matched* when its score is at or above the threshold; a matched
query is a true positive when its match is acceptable (ground truth), else a false positive. As in paper 000:

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

from driftmap.errors import BadInputError

__all__ = ["PlaceMetrics", "PrCurve", "evaluate_matches", "match_correct", "pr_curve"]

F64 = NDArray[np.float64]
BoolArr = NDArray[np.bool_]


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
