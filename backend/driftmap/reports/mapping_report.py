"""The paper's Table I and Fig. 6, reproduced on a site whose mapping drives carry ground truth.

Variants ([SSLAM], V-A): (a) visual odometry only, (b) odometry + automatic loop closure, (c) odometry +
manual groundings, (d) the full system. (a) and (b) start each drive from its first frame's true pose,
since nothing else places them. The error is the mean over every mapping frame of the distance between
the estimated and the true floor point under the camera, metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from driftmap.core.mapping.pipeline import (
    MapBuild,
    MappingDrive,
    MappingParams,
    prepare_drives,
    solve_map,
    variant,
)
from driftmap.core.topomap.database import DATABASE_OFF
from driftmap.errors import BadInputError
from driftmap.reports.plots import draw_plan, new_figure, save

VARIANTS: tuple[tuple[str, str, bool, bool], ...] = (
    ("a", "visual odometry", False, False),
    ("b", "odometry + loop closure", True, False),
    ("c", "odometry + groundings", False, True),
    ("d", "full system", True, True),
)


@dataclass(frozen=True)
class VariantResult:
    """One row of Table I."""

    key: str
    label: str
    mean_error_m: float
    median_error_m: float
    max_error_m: float
    closures_accepted: int
    false_closures: int
    """Accepted closures whose frames are truly more than 3 m apart."""


@dataclass(frozen=True, eq=False)
class MappingReport:
    rows: tuple[VariantResult, ...]
    builds: dict[str, MapBuild]
    figure: Path | None

    def table(self) -> str:
        """Table I as aligned text."""
        lines = [f"{'variant':<32}{'mean m':>9}{'median m':>10}{'max m':>9}{'closures':>10}{'false':>7}"]
        for r in self.rows:
            lines.append(
                f"({r.key}) {r.label:<28}{r.mean_error_m:>9.2f}{r.median_error_m:>10.2f}{r.max_error_m:>9.2f}"
                f"{r.closures_accepted:>10d}{r.false_closures:>7d}"
            )
        full = self.rows[-1].mean_error_m
        best_other = min(r.mean_error_m for r in self.rows[:-1])
        lines.append(f"full system vs best other: {best_other / max(full, 1e-9):.2f}x lower error")
        return "\n".join(lines)


def errors_m(
    poses: Sequence[NDArray[np.float64]], truth: Sequence[NDArray[np.float64]]
) -> NDArray[np.float64]:
    """Distances between estimated and true positions over all frames of all drives, metres."""
    return np.concatenate(
        [np.linalg.norm(p[:, :2] - t[:, :2], axis=1) for p, t in zip(poses, truth, strict=True)]
    )


def false_closures(build: MapBuild, truth: Sequence[NDArray[np.float64]], tolerance_m: float = 3.0) -> int:
    """Accepted closures whose two frames are truly further apart than ``tolerance_m``."""
    bad = 0
    for c in build.closures:
        if c.accepted:
            gap = np.linalg.norm(truth[c.drive_a][c.frame_a, :2] - truth[c.drive_b][c.frame_b, :2])
            bad += int(gap > tolerance_m)
    return bad


def run_mapping_report(
    drives: Sequence[MappingDrive],
    truth: Sequence[NDArray[np.float64] | None],
    params: MappingParams,
    *,
    plan_layers: dict[str, Any] | None = None,
    figure_path: Path | None = None,
    progress: Any = None,
    workers: int = 1,
) -> MappingReport:
    """Build the four Table I variants once each (odometry and loop search shared) and score them."""
    if any(t is None for t in truth):
        raise BadInputError("every mapping frame needs ground truth (x, y, yaw in frames.csv) for --truth")
    true = [t for t in truth if t is not None]
    started = [
        replace(d, start_wT=(float(t[0, 0]), float(t[0, 1]), float(t[0, 2])))
        for d, t in zip(drives, true, strict=True)
    ]
    prepared = prepare_drives(started, params, progress, workers)
    rows, builds = [], {}
    for key, label, loops, groundings in VARIANTS:
        # Table I scores poses only: skip the localisation database (SESAME reads every frame again).
        settings = replace(variant(params, loops=loops, groundings=groundings), database=DATABASE_OFF)
        build = solve_map(prepared, started, settings)
        err = errors_m(build.wTi, true)
        builds[key] = build
        rows.append(
            VariantResult(
                key,
                label,
                float(err.mean()),
                float(np.median(err)),
                float(err.max()),
                int(sum(c.accepted for c in build.closures)),
                false_closures(build, true),
            )
        )
    report = MappingReport(tuple(rows), builds, figure_path)
    if figure_path is not None:
        draw_figure(report, true, plan_layers or {}, figure_path)
    return report


def draw_figure(
    report: MappingReport, truth: Sequence[NDArray[np.float64]], plan: dict[str, Any], path: Path
) -> None:
    """Fig. 6: each variant's trajectories (coloured) over the survey plan (grey) and the truth (black)."""
    origin = (float(min(t[:, 0].min() for t in truth)), float(min(t[:, 1].min() for t in truth)))
    fig, axes = new_figure(len(report.rows) + 1, 1, 4.5)
    panels = [("ground truth", truth, None)] + [
        (f"({r.key}) {r.label}: {r.mean_error_m:.2f} m", report.builds[r.key].wTi, r) for r in report.rows
    ]
    for ax, (title, poses, _row) in zip(axes, panels, strict=True):
        draw_plan(ax, plan, origin)
        for k, p in enumerate(poses):
            ax.plot(p[:, 0] - origin[0], p[:, 1] - origin[1], linewidth=0.9, color=f"C{k % 10}", zorder=2)
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
        ax.set_xlabel(f"x - {origin[0]:.0f} m", fontsize=7)
        ax.set_ylabel(f"y - {origin[1]:.0f} m", fontsize=7)
    path.parent.mkdir(parents=True, exist_ok=True)
    save(fig, str(path))
