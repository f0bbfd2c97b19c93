"""Precision-recall of place recognition by sweeping the match threshold (paper 000 Fig. 9, paper 001 Fig. 12).

Every query frame gets one estimate with a confidence score. At threshold X a frame is *matched* when its
score is >= X; a matched frame is a true positive when its estimate lies within the ground-truth tolerance.
Precision = TP / matched, recall = TP / all query frames (every query frame has a true place in the map).
Sweeping X from the highest score down traces the curve; ties are taken together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["PrCurve", "pr_curve"]

F64 = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PrCurve:
    """A precision-recall curve and its summary figures.

    Attributes:
        precision: (K,) float64 precision at each distinct threshold, highest threshold first.
        recall: (K,) float64 recall at the same thresholds, non-decreasing.
        thresholds: (K,) float64 the score thresholds.
    """

    precision: F64
    recall: F64
    thresholds: F64

    @property
    def auc(self) -> float:
        """Area under the curve as average precision: sum over thresholds of recall gain x precision."""
        if self.recall.size == 0:
            return 0.0
        gain = np.diff(np.r_[0.0, self.recall])
        return float(np.sum(gain * self.precision))

    @property
    def recall_at_full_precision(self) -> float:
        """The largest recall reached while precision is still 1 (0 when the top match is wrong)."""
        ok = np.flatnonzero(self.precision < 1.0)
        last = self.recall.size if ok.size == 0 else int(ok[0])
        return float(self.recall[last - 1]) if last > 0 else 0.0

    def threshold_at_full_precision(self) -> float:
        """The lowest threshold with precision 1 (inf when there is none)."""
        ok = np.flatnonzero(self.precision < 1.0)
        last = self.recall.size if ok.size == 0 else int(ok[0])
        return float(self.thresholds[last - 1]) if last > 0 else float("inf")


def pr_curve(scores: NDArray[np.floating], correct: NDArray[np.bool_]) -> PrCurve:
    """The precision-recall curve of one set of query frames.

    Args:
        scores: (N,) confidence of each frame's estimate, higher = more confident; NaN never matches.
        correct: (N,) bool, the estimate lies within the ground-truth tolerance.

    Returns:
        :class:`PrCurve` with one point per distinct finite score.
    """
    s = np.asarray(scores, dtype=np.float64)
    c = np.asarray(correct, dtype=bool)
    if s.shape != c.shape or s.ndim != 1:
        raise ValueError(f"scores and correct must be (N,), got {s.shape} and {c.shape}")
    n = s.size
    keep = np.isfinite(s)
    s, c = s[keep], c[keep]
    order = np.argsort(-s, kind="stable")
    s, c = s[order], c[order]
    tp = np.cumsum(c)
    last_of_tie = np.r_[s[1:] != s[:-1], True] if s.size else np.zeros(0, dtype=bool)
    idx = np.flatnonzero(last_of_tie)
    matched = idx + 1.0
    return PrCurve(
        precision=tp[idx] / matched,
        recall=tp[idx] / max(n, 1),
        thresholds=s[idx],
    )
