"""Localisation evaluated like both papers: precision-recall per condition and method ([SSLAM] Fig. 9).

Every localisation drive with ground truth is run through four localisers on the same stored map version:
holistic single-image SAD, single-image SAD with SESAME, the HMM filter with SAD, and the HMM with SESAME.
As in [SESAME], "SESAME" is the whole method: salient query masks (eq. 6) against the SESAME database
(quality filter and Algorithm 1); the holistic methods compare whole images against [SSLAM]'s plain
references (a few frames per node), when the map version holds both. Drives are grouped by condition from their names: ``*-dust1``, ``*-dust2``, ``*-water1``,
``*-water2`` (the simulator's obscured copies, [SSLAM] IV-A) and ``clean`` for the rest.

A frame's estimate is right when its node centre lies within ``tolerance_m`` of the true floor point
(15 m for the simulator; [SSLAM] used 30 m in a larger mine). Sweeping the match threshold X_thresh over
each method's score gives the precision-recall curve (:mod:`driftmap.core.place_recognition.metrics`). The match rule is
the one the localiser applies (eq. 12 and driftmap's lost detection): a frame the filter counts as lost is
never matched, at any threshold. The table gives the curve's area, the recall at 100 % precision (also when
frames are ranked by the estimate's ``confidence``, the posterior times the track's distinctness), the share
of frames the localiser marks matched at its configured X_thresh and their mean distance error (node centre
to truth, metres).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from driftmap.core.localisation import hmm
from driftmap.core.localisation.localiser import Localiser
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.localisation.motion import OdometryFeed
from driftmap.core.sesame.masks import SesameParams
from driftmap.core.types import ProgressFn
from driftmap.errors import BadInputError
from driftmap.reports.localisation_results import (
    CONDITIONS,
    DEFAULT_METHOD,
    METHODS,
    LocalisationReport,
    MethodResult,
    condition_of,
)
from driftmap.reports.plots import new_figure, save
from driftmap.services.localisation import RecordedDrive

__all__ = ["run_localisation_report"]

_COLOURS = {
    "SAD": "#9a9a9a",
    "SAD+SESAME": "#3a7bd5",
    "HMM+SAD": "#e08a2e",
    "HMM+SESAME": "#c0392b",
    "HMM+SESAME+odometry": "#1e8449",
}


def _run_drive(
    drive: RecordedDrive,
    localisers: dict[str, tuple[Localiser, bool]],
    results: dict[str, MethodResult],
    stride: int,
) -> None:
    """Every method on one drive; the frame is pre-processed, masked and its odometry step measured once,
    shared by the methods (``localisers``: name -> (localiser, uses odometry)).

    Single-image methods see every ``stride``-th frame only (they keep no state between frames).
    """
    if drive.truth_xy_m is None:
        raise BadInputError(f"drive {drive.name!r} has no ground truth on every frame", field="truth")
    plain = next(iter(localisers.values()))[0]  # every method's map has the version's image params
    masker = next((loc for loc, _o in localisers.values() if loc.sesame is not None), None)
    feed = OdometryFeed(drive.camera) if drive.camera is not None else None
    for k, frame in enumerate(drive.frames()):
        thumb = plain.thumbnail(frame)
        t0 = time.perf_counter()
        mask = masker.query_mask(frame) if masker is not None else None
        mask_ms = (time.perf_counter() - t0) * 1e3  # charged to the SESAME methods only
        t0 = time.perf_counter()
        motion = feed.step(frame, float(drive.t_s[k])) if feed is not None else None
        odometry_ms = (time.perf_counter() - t0) * 1e3  # charged to the odometry method only
        for name, (loc, odometry) in localisers.items():
            if loc.single_image and k % stride:
                continue
            masked = mask if loc.sesame is not None else None
            est = loc.step(thumb, float(drive.t_s[k]), masked, motion if odometry else None)
            res = results[name]
            res.scores.append(float("nan") if est.lost else est.score)  # lost: never matched
            res.confidence.append(float("nan") if est.lost else est.confidence)
            res.raw.append(float("nan") if est.lost else est.raw_confidence)
            res.error_m.append(
                float(np.hypot(est.x_m - drive.truth_xy_m[k, 0], est.y_m - drive.truth_xy_m[k, 1]))
            )
            res.matched.append(est.matched)
            res.drive.append(drive.name)
            extra = (mask_ms if loc.sesame is not None else 0.0) + (odometry_ms if odometry else 0.0)
            res.ms.append(est.ms + extra)


def run_localisation_report(
    lmap: LocaliserMap,
    drives: Sequence[RecordedDrive],
    sesame: SesameParams,
    *,
    tolerance_m: float = 15.0,
    out_dir: Path | None = None,
    params: hmm.HmmParams = hmm.DEFAULT,
    single_image_stride: int = 1,
    holistic_map: LocaliserMap | None = None,
    known_start: bool = False,
    progress: ProgressFn | None = None,
    methods: Sequence[str] | None = None,
) -> LocalisationReport:
    """Run the four methods over every drive, score them, and write the PNG and the table.

    Args:
        lmap: the localiser's map of the version evaluated.
        drives: localisation drives with ground truth (their names give the condition).
        sesame: SESAME mask parameters of the SESAME methods.
        tolerance_m: a frame is right when its node centre is within this of the truth, metres.
        out_dir: folder for ``localisation_pr.png`` and ``localisation_table.md``; None writes nothing.
        params: HMM parameters of the temporal methods.
        single_image_stride: single-image methods score every this-many-th frame (they compare the
            whole map each frame; the HMM methods always see every frame).
        holistic_map: the references of the holistic methods ([SSLAM]'s plain selection); None: ``lmap``.
        known_start: the HMM methods start each drive at the node nearest its first true floor point, as
            [SSLAM] does ("X_0 is initialized to the starting position ... known prior to vehicle
            operation"); False starts them global (uniform), which driftmap must also survive.
        progress: called with (drive name, fraction of drives done).
        methods: the labels of :data:`METHODS` to run; None: all.

    Returns:
        :class:`LocalisationReport`.
    """
    if not drives:
        raise BadInputError("no localisation drive with ground truth to evaluate", field="drives")
    if single_image_stride < 1:
        raise BadInputError(f"must be >= 1, got {single_image_stride}", field="single_image_stride")
    if not tolerance_m > 0:
        raise BadInputError(f"must be positive, got {tolerance_m}", field="tolerance_m")
    unknown = sorted(set(methods or ()) - {name for name, *_ in METHODS})
    if unknown:
        known = ", ".join(name for name, *_ in METHODS)
        raise BadInputError(f"unknown method {unknown[0]!r} (one of {known})", field="methods")
    chosen = [m for m in METHODS if methods is None or m[0] in methods]
    report = progress or (lambda _stage, _fraction: None)
    results: dict[tuple[str, str], MethodResult] = {}
    order = sorted(range(len(drives)), key=lambda i: CONDITIONS.index(condition_of(drives[i].name)))
    for done, i in enumerate(order):
        drive = drives[i]
        cond = condition_of(drive.name)
        report(drive.name, done / len(drives))
        start = (
            lmap.nearest_node(*drive.truth_xy_m[0]) if known_start and drive.truth_xy_m is not None else None
        )
        localisers = {
            name: (
                Localiser(
                    lmap if masked or holistic_map is None else holistic_map,
                    params,
                    single_image=not temporal,
                    sesame=sesame if masked else None,
                    start_node=start if temporal else None,
                    lens=drive.camera.lens if drive.camera is not None else None,
                ),
                odometry,
            )
            for name, masked, temporal, odometry in chosen
        }
        per = {name: results.setdefault((cond, name), MethodResult()) for name, *_ in chosen}
        _run_drive(drive, localisers, per, single_image_stride)
    report("done", 1.0)
    figure = table_path = None
    result = LocalisationReport(results, tolerance_m, None, None, known_start)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        figure = _plot(result, out_dir / "localisation_pr.png")
        _plot_reliability(result, out_dir / "localisation_reliability.png")
        table_path = out_dir / "localisation_table.md"
        table_path.write_text(result.table() + "\n", encoding="utf-8")
    return LocalisationReport(results, tolerance_m, figure, table_path, known_start)


def _plot(result: LocalisationReport, path: Path) -> Path:
    conditions = [c for c in CONDITIONS if any(k[0] == c for k in result.results)]
    fig, axes = new_figure(len(conditions), 1, size_in=3.6)
    for ax, cond in zip(axes, conditions, strict=True):
        for name, *_ in METHODS:
            r = result.results.get((cond, name))
            if r is None:
                continue
            curve = r.curve(result.tolerance_m)
            ax.plot(
                np.r_[0.0, curve.recall],
                np.r_[1.0, curve.precision],
                color=_COLOURS[name],
                label=f"{name} ({curve.auc:.2f})",
                linewidth=1.4,
            )
        start = ", known start" if result.known_start else ""
        ax.set_title(f"{cond}, {result.tolerance_m:g} m tolerance{start}")
        ax.set_xlabel("recall")
        ax.set_ylabel("precision")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=7)
    save(fig, str(path))
    return path


def _plot_reliability(result: LocalisationReport, path: Path) -> Path:
    """The default method's reliability diagram per condition: share right against reported confidence."""
    fig, axes = new_figure(1, 1, size_in=4.2)
    ax = axes[0]
    ax.plot([0, 1], [0, 1], color="#555555", linestyle=":", linewidth=1, label="calibrated")
    for cond in CONDITIONS:
        r = result.results.get((cond, DEFAULT_METHOD))
        if r is None:
            continue
        rel = r.reliability(result.tolerance_m)
        ok = rel.counts > 0
        ax.plot(
            rel.mean_confidence[ok],
            rel.right_share[ok],
            marker="o",
            markersize=3,
            linewidth=1.2,
            label=f"{cond} (ECE {rel.expected_calibration_error:.3f})",
        )
    ax.set_title(f"{DEFAULT_METHOD}: reliability, {result.tolerance_m:g} m tolerance")
    ax.set_xlabel("reported confidence")
    ax.set_ylabel("share of frames right")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=7)
    save(fig, str(path))
    return path
