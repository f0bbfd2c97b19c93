"""Commands of the mapping pipeline: odometry of one drive, map builds, exports, Table I report."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import typer
from rich.table import Table

from driftmap.cli.common import JsonOption, console, open_storage, print_json, stage_progress, user_errors
from driftmap.config import get_settings
from driftmap.core.mapping.pipeline import MAP_PRESETS, MappingParams
from driftmap.core.odometry.drive import dead_reckon
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, OdometryModel
from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import PoseRow, write_poses_csv
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder
from driftmap.formats.frame_images import decode_gray
from driftmap.reports.mapping_report import run_mapping_report
from driftmap.services import map_pieces
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services.residuals import ResidualSummary, residual_rows, summarise

map_app = typer.Typer(help="Map versions: build, show, export.", no_args_is_help=True)
report_app = typer.Typer(help="Evaluation reports against ground truth.", no_args_is_help=True)

PresetName = Literal["paper", "fast"]
"""The names of :data:`~driftmap.core.mapping.pipeline.MAP_PRESETS` (a test keeps them equal)."""
PresetOption = Annotated[PresetName, typer.Option("--preset", help="Parameter preset.")]
DEFAULT_WORKERS = min(2, os.cpu_count() or 1)
WorkersOption = Annotated[
    int,
    typer.Option("--workers", min=1, help="Drives dead-reckoned at once (threads; default: up to 2 cores)."),
]


def _preset(name: str) -> MappingParams:
    if name not in MAP_PRESETS:
        raise BadInputError(f"unknown preset {name!r}; choose {', '.join(MAP_PRESETS)}", field="--preset")
    return MAP_PRESETS[name]


def odometry(
    drive_dir: Annotated[Path, typer.Argument(help="A drive folder (formats.md).")],
    out: Annotated[Path, typer.Option("--out", help="Poses CSV to write (drive,frame,x,y,yaw).")],
    model: Annotated[
        OdometryModel, typer.Option(help="auto, linear (eq. 1-2) or homography (bird's-eye).")
    ] = "auto",
) -> None:
    """Dead-reckon one drive with ground-plane visual odometry (from its first true pose when known)."""
    with user_errors():
        folder = read_drive_folder(drive_dir)
        first = folder.frames[0]
        start = (first.x_m, first.y_m, first.yaw_rad) if first.has_truth else (0.0, 0.0, 0.0)
        frames = (decode_gray(data, str(drive_dir)) for _row, data in iter_frame_images(folder))
        params = replace(ODOMETRY_DEFAULT, model=model)
        result = dead_reckon(
            frames, folder.meta.camera, params, (start[0] or 0.0, start[1] or 0.0, start[2] or 0.0)
        )
        rows = [
            PoseRow(folder.meta.name, f.frame, float(p[0]), float(p[1]), float(p[2]))
            for f, p in zip(folder.frames, result.wTi, strict=True)
        ]
        write_poses_csv(out, rows)
    console.print(
        f"wrote {len(rows)} poses to {out} ({np.median(result.ms_per_step):.1f} ms per step, median)"
    )
    if all(f.has_truth for f in folder.frames):
        truth = np.array([[f.x_m, f.y_m] for f in folder.frames], dtype=np.float64)
        travelled = float(np.linalg.norm(np.diff(truth, axis=0), axis=1).sum())
        final = float(np.linalg.norm(result.wTi[-1, :2] - truth[-1]))
        console.print(
            f"final position error {final:.2f} m over {travelled:.1f} m ({100 * final / max(travelled, 1e-9):.1f}%)"
        )


@map_app.command("build")
def map_build(
    site: Annotated[str, typer.Argument(help="Site name.")],
    preset: PresetOption = "paper",
    workers: WorkersOption = DEFAULT_WORKERS,
    as_json: JsonOption = False,
    full: Annotated[
        bool,
        typer.Option(
            "--full",
            help="Prepare every drive again and search loop closures afresh instead of reusing what was kept.",
        ),
    ] = False,
) -> None:
    """Build a new immutable map version from the site's mapping drives and groundings (the odometry, the
    loop-closure scores and the database's pair scores of drives unchanged since the last build reused)."""
    storage = open_storage()
    with user_errors():
        params = _preset(preset)
        stale: set[str] = set()
        with storage.blobs.batch() as batch, storage.db.session() as session:
            record = site_service.get_site(session, site)
            map_service.ensure_buildable(session, record)
            with stage_progress("map build") as report:
                version, build = map_service.build_site_map(
                    session,
                    storage.blobs,
                    batch,
                    record,
                    params,
                    report,
                    workers=workers,
                    full=full,
                    stale=stale,
                )
            number = version.version
        map_pieces.drop_stale(storage, stale)
    if as_json:
        print_json({"site": site, "version": number, "stats": map_service.json_safe(build.stats)})
        return
    console.print(f"map version {number} of {site!r}: {_stats_line(build.stats)}")


def _stats_line(stats: dict[str, float | int]) -> str:
    keys = ("frames", "keyframes", "closures_found", "closures_accepted", "groundings", "nodes")
    seconds = sum(float(v) for k, v in stats.items() if k.endswith("_s"))
    line = ", ".join(f"{k.replace('_', ' ')} {stats.get(k, 0)}" for k in keys) + f"; {seconds:.1f} s"
    if "segments_reused" in stats:
        reused, prepared = stats["segments_reused"], stats.get("segments_prepared", 0)
        line += f"; odometry of {reused} of {reused + prepared} drive segments reused"
    if "loop_queries_reused" in stats:
        kept, scored = stats["loop_queries_reused"], stats.get("loop_queries_scored", 0)
        line += f", loop-closure scores of {kept} of {kept + scored} keyframes"
    if "database_pairs_reused" in stats:
        kept, scored = stats["database_pairs_reused"], stats.get("database_pairs_scored", 0)
        line += f", database pair scores {kept} of {kept + scored}"
    return line


@map_app.command("show")
def map_show(
    site: Annotated[str, typer.Argument(help="Site name.")],
    version: Annotated[int | None, typer.Option(help="Map version (default: latest).")] = None,
    as_json: JsonOption = False,
) -> None:
    """Summarise a map version: build figures, the grounding residuals (largest first) and their RMS, mean
    and max per drive and overall, metres."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        record = map_service.get_map_version(session, site_service.get_site(session, site), version)
        if as_json:
            rows = residual_rows(session, record)
            document = {
                "site": site,
                "version": record.version,
                "created_at": record.created_at,
                "created_by": record.created_by,
                "stats": record.stats,
                "residuals": rows,
                "summary": summarise(record.version, rows),
            }
            print_json(document)
            return
        console.print(
            f"map version {record.version} of {site!r}, built {record.created_at:%Y-%m-%d %H:%M} by {record.created_by}"
        )
        console.print(_stats_line(record.stats))
        rows = residual_rows(session, record)
        stations = any(row.station for row in rows)  # the column only when a grounding names its station
        table = Table("drive", "frame", *(["station"] if stations else []), "surveyed x", "surveyed y")
        for header in ("dx m", "dy m", "distance m"):
            table.add_column(header)
        for row in rows:
            table.add_row(
                row.drive,
                str(row.frame),
                *([row.station or ""] if stations else []),
                f"{row.surveyed_x_m:.2f}",
                f"{row.surveyed_y_m:.2f}",
                f"{row.dx_m:+.2f}",
                f"{row.dy_m:+.2f}",
                f"{row.distance_m:.2f}",
            )
    console.print(table)
    console.print(_summary_table(summarise(record.version, rows)))


def _summary_table(summary: ResidualSummary) -> Table:
    table = Table(
        "drive", "groundings", "RMS m", "mean m", "max m", title="residuals over the groundings used"
    )
    lines = [(d.drive, d.stats) for d in summary.drives] + [("all", summary.overall)]
    for name, stats in lines:
        table.add_row(
            name, str(stats.count), f"{stats.rms_m:.2f}", f"{stats.mean_m:.2f}", f"{stats.max_m:.2f}"
        )
    return table


@report_app.command("mapping")
def report_mapping(
    site: Annotated[str, typer.Argument(help="Site name.")],
    truth: Annotated[bool, typer.Option("--truth", help="Score against the drives' ground truth.")] = False,
    out: Annotated[
        Path | None, typer.Option(help="Folder for the PNG (default: DATA_DIR/reports/SITE).")
    ] = None,
    preset: PresetOption = "paper",
    workers: WorkersOption = DEFAULT_WORKERS,
    as_json: JsonOption = False,
) -> None:
    """The paper's Table I (VO, VO+loops, VO+groundings, full) and a Fig. 6-style PNG."""
    storage = open_storage()
    with user_errors():
        if not truth:
            raise BadInputError("the mapping report needs ground truth: pass --truth", field="--truth")
        params = _preset(preset)
        folder = out or get_settings().data_dir / "reports" / site
        with storage.db.session() as session:
            record = site_service.get_site(session, site)
            loaded = map_service.load_site_drives(session, storage.blobs, record)
            plan = site_service.latest_survey_map(session, record).layers
        with stage_progress("Table I") as report:
            result = run_mapping_report(
                loaded.inputs,
                loaded.truth,
                params,
                plan_layers=plan,
                figure_path=folder / "mapping.png",
                progress=report,
                workers=workers,
            )
    console.print(result.table())
    console.print(f"figure: {result.figure}")
