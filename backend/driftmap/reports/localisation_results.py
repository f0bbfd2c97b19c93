"""What the localisation report measures: the methods and conditions compared, and per-frame outcomes.

:data:`METHODS` are the localisers run on every drive, :data:`CONDITIONS` the groups of drives by their
names' suffix (:func:`condition_of`); a :class:`MethodResult` holds one method's per-frame outcomes on one
condition and a :class:`LocalisationReport` all of them, with the table of
:func:`driftmap.reports.localisation_report.run_localisation_report`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from driftmap.core.place_recognition.metrics import (
    PrCurve,
    Reliability,
    fit_calibration,
    pr_curve,
    reliability,
)

__all__ = [
    "CONDITIONS",
    "DEFAULT_METHOD",
    "METHODS",
    "LocalisationReport",
    "MethodResult",
    "condition_of",
]

CONDITIONS = ("clean", "dust1", "dust2", "water1", "water2")
#: (label, SESAME masks, HMM temporal filter, odometry); the last is the product's default
METHODS: tuple[tuple[str, bool, bool, bool], ...] = (
    ("SAD", False, False, False),
    ("SAD+SESAME", True, False, False),
    ("HMM+SAD", False, True, False),
    ("HMM+SESAME", True, True, False),
    ("HMM+SESAME+odometry", True, True, True),
)
DEFAULT_METHOD = METHODS[-1][0]
_CONDITION = re.compile(r"-((?:dust|water)\d)$")


def condition_of(drive_name: str) -> str:
    """``dust1``/``dust2``/``water1``/``water2`` from a drive name's suffix, else ``clean``."""
    found = _CONDITION.search(drive_name)
    return found.group(1) if found else "clean"


@dataclass(eq=False)
class MethodResult:
    """Per-frame outcomes of one method on one condition (every drive of it, concatenated).

    Attributes:
        scores: (N,) the paper's X_i(b(i)) of each frame's estimate; NaN for a lost frame (never matched).
        confidence: (N,) the reported confidence (:attr:`driftmap.core.localisation.state.Estimate.confidence`,
            calibrated); NaN for a lost frame.
        raw: (N,) the confidence before calibration (X x the track's distinctness); NaN for a lost frame.
        error_m: (N,) distance from the reported position to the true floor point, metres.
        matched: (N,) the localiser's own match flag (confidence at its threshold, not lost).
        ms: (N,) milliseconds per frame.
        drive: (N,) the drive of each frame.
    """

    scores: list[float] = field(default_factory=list)
    confidence: list[float] = field(default_factory=list)
    raw: list[float] = field(default_factory=list)
    error_m: list[float] = field(default_factory=list)
    matched: list[bool] = field(default_factory=list)
    ms: list[float] = field(default_factory=list)
    drive: list[str] = field(default_factory=list)

    def curve(self, tolerance_m: float, by_confidence: bool = False) -> PrCurve:
        """The precision-recall curve at this ground-truth tolerance, sweeping a threshold over the paper's
        X (``by_confidence``: over the reported confidence instead)."""
        scores = np.asarray(self.confidence if by_confidence else self.scores, dtype=np.float64)
        return pr_curve(scores, np.asarray(self.error_m) <= tolerance_m, recallable=max(scores.size, 1))

    def only(self, drive: str) -> MethodResult:
        """The frames of one drive."""
        keep = [k for k, d in enumerate(self.drive) if d == drive]
        return MethodResult(
            [self.scores[k] for k in keep],
            [self.confidence[k] for k in keep],
            [self.raw[k] for k in keep],
            [self.error_m[k] for k in keep],
            [self.matched[k] for k in keep],
            [self.ms[k] for k in keep],
            [self.drive[k] for k in keep],
        )

    def matched_errors_m(self) -> NDArray[np.float64]:
        """(K,) distance errors of the matched frames, metres."""
        m = np.asarray(self.matched, dtype=bool)
        return np.asarray(self.error_m, dtype=np.float64)[m] if m.size else np.zeros(0)

    def matched_error_m(self) -> float:
        """Mean distance error of the matched frames, metres (NaN when none matched)."""
        e = self.matched_errors_m()
        return float(np.mean(e)) if e.size else float("nan")

    def reported_error_m(self) -> float:
        """Mean distance error of every frame not lost, metres (NaN when none)."""
        e = np.asarray(self.error_m)[np.isfinite(np.asarray(self.confidence, dtype=np.float64))]
        return float(np.mean(e)) if e.size else float("nan")

    def reliability(self, tolerance_m: float) -> Reliability:
        """The reported confidence's reliability diagram (lost frames left out)."""
        right = np.asarray(self.error_m) <= tolerance_m
        return reliability(np.asarray(self.confidence, dtype=np.float64), right)


def _pct(errors: NDArray[np.float64], q: float) -> float:
    return float(np.percentile(errors, q)) if errors.size else float("nan")


@dataclass(frozen=True, eq=False)
class LocalisationReport:
    """Results by (condition, method) and the files written."""

    results: dict[tuple[str, str], MethodResult]
    tolerance_m: float
    figure: Path | None
    table_path: Path | None
    known_start: bool = False

    def rows(self) -> list[dict[str, float | str | int]]:
        """One row per (condition, method): AUC, recall@100% precision by X and by the confidence, matched
        share, position errors and the confidence's calibration error."""
        out: list[dict[str, float | str | int]] = []
        for (cond, method), r in self.results.items():
            curve = r.curve(self.tolerance_m)
            errors = r.matched_errors_m()
            out.append(
                {
                    "condition": cond,
                    "method": method,
                    "frames": len(r.scores),
                    "auc": curve.auc,
                    "recall_at_p100": curve.recall_at_full_precision,
                    "recall_at_p100_confidence": r.curve(
                        self.tolerance_m, by_confidence=True
                    ).recall_at_full_precision,
                    "matched": float(np.mean(r.matched)) if r.matched else 0.0,
                    "matched_error_m": r.matched_error_m(),
                    "matched_p95_m": _pct(errors, 95),
                    "matched_max_m": float(errors.max()) if errors.size else float("nan"),
                    "reported_error_m": r.reported_error_m(),
                    "ece": r.reliability(self.tolerance_m).expected_calibration_error,
                    "ms_per_frame": float(np.median(r.ms)) if r.ms else float("nan"),
                }
            )
        return out

    def table(self) -> str:
        """The tables as Markdown: per (condition, method), then the default method per drive."""
        clean = {row["method"]: float(row["auc"]) for row in self.rows() if row["condition"] == "clean"}
        lines = [
            "| condition | method | frames | AUC | AUC - clean | recall @ 100% P by X | by confidence "
            "| matched | error of matched: mean / p95 / max (m) | error of all reported (m) | ECE | ms/frame |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for row in self.rows():
            delta = float(row["auc"]) - clean.get(str(row["method"]), float("nan"))
            lines.append(
                f"| {row['condition']} | {row['method']} | {row['frames']} | {float(row['auc']):.3f} "
                f"| {delta:+.3f} | {float(row['recall_at_p100']):.3f} "
                f"| {float(row['recall_at_p100_confidence']):.3f} | {100 * float(row['matched']):.0f}% "
                f"| {float(row['matched_error_m']):.2f} / {float(row['matched_p95_m']):.2f} "
                f"/ {float(row['matched_max_m']):.1f} | {float(row['reported_error_m']):.2f} "
                f"| {float(row['ece']):.3f} | {float(row['ms_per_frame']):.1f} |"
            )
        start = (
            "at each drive's known start (the SSLAM paper X_0)" if self.known_start else "global (uniform)"
        )
        lines.append(f"\nHMM belief started {start}; {self.tolerance_m:g} m tolerance.\n")
        lines += [
            f"{DEFAULT_METHOD}, each drive on its own:\n",
            "| drive | frames | recall @ 100% P by confidence | by X | matched | error of matched: "
            "mean / p95 / max (m) |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for cond in CONDITIONS:
            pooled = self.results.get((cond, DEFAULT_METHOD))
            for name in sorted(set(pooled.drive) if pooled is not None else ()):
                r = pooled.only(name) if pooled is not None else MethodResult()
                e = r.matched_errors_m()
                lines.append(
                    f"| {name} | {len(r.scores)} "
                    f"| {r.curve(self.tolerance_m, True).recall_at_full_precision:.3f} "
                    f"| {r.curve(self.tolerance_m).recall_at_full_precision:.3f} "
                    f"| {100 * float(np.mean(r.matched)) if r.matched else 0.0:.0f}% "
                    f"| {r.matched_error_m():.2f} / {_pct(e, 95):.2f} / "
                    f"{float(e.max()) if e.size else float('nan'):.1f} |"
                )
        return "\n".join(lines)

    def calibration(self) -> tuple[tuple[float, float], ...] | None:
        """The calibration (``HmmParams.calibration`` knots) the default method's raw confidence would get
        from these drives (every condition pooled); None without the default method or without both right
        and wrong frames."""
        raw: list[float] = []
        right: list[bool] = []
        for (_cond, method), r in self.results.items():
            if method == DEFAULT_METHOD:
                raw += r.raw
                right += [e <= self.tolerance_m for e in r.error_m]
        try:
            return fit_calibration(np.asarray(raw, dtype=np.float64), np.asarray(right, dtype=bool))
        except ValueError:
            return None
