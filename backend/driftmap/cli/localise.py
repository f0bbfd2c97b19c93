"""Commands of localisation: a recorded drive against a stored map, and the localisation report."""

from __future__ import annotations

from enum import Enum
from fnmatch import fnmatch
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from driftmap.cli.common import console, open_storage, stage_progress, user_errors
from driftmap.config import get_settings
from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import write_localisation_csv
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder
from driftmap.formats.frame_images import decode_gray
from driftmap.reports.localisation_report import run_localisation_report
from driftmap.reports.localisation_results import METHODS
from driftmap.services import localisation as loc_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service

MethodName = Enum(  # type: ignore[misc]
    "MethodName", {name: name for name, *_ in METHODS}, type=str
)
"""``--method`` choices: the labels of :data:`driftmap.reports.localisation_results.METHODS`."""


def localise(
    site: Annotated[str, typer.Argument(help="Site name (its map is used).")],
    drive_dir: Annotated[Path, typer.Argument(help="A drive folder (formats.md) to localise.")],
    out: Annotated[Path, typer.Option("--out", help="CSV to write (frame,node,x,y,score,matched).")],
    map_version: Annotated[
        int | None, typer.Option("--map-version", help="Map version (default: latest).")
    ] = None,
    sesame: Annotated[
        bool,
        typer.Option(
            "--sesame/--no-sesame",
            help="SESAME masks (eq. 6) and salient database; --no-sesame: holistic SAD on the SSLAM paper's references.",
        ),
    ] = True,
    temporal: Annotated[
        bool, typer.Option("--temporal/--no-temporal", help="HMM temporal filter (the SSLAM paper III-B).")
    ] = True,
    start: Annotated[
        str | None,
        typer.Option(
            "--start",
            help="The vehicle's known start 'X,Y' (survey frame, metres); default: unknown (global start).",
        ),
    ] = None,
    start_radius_m: Annotated[
        float,
        typer.Option("--start-radius-m", min=0.0, help="Spread the known start over this radius, metres."),
    ] = 0.0,
    odometry: Annotated[
        bool,
        typer.Option(
            "--odometry/--no-odometry",
            help="Ground-plane odometry of the drive's camera moves the belief and the position.",
        ),
    ] = True,
) -> None:
    """Localise every frame of a recorded drive against the site's map: best node, position, confidence."""
    storage = open_storage()
    with user_errors():
        start_xy_m = _survey_point(start, "--start") if start is not None else None
        folder = read_drive_folder(drive_dir)
        with storage.db.session() as session:
            record = site_service.get_site(session, site)
            version = map_service.get_map_version(session, record, map_version)
            lmap = loc_service.load_version_localiser_map(
                session, storage.blobs, version, holistic=not sesame
            )
            sesame_params = loc_service.sesame_params_of(version) if sesame else None
            number = version.version
        localiser = loc_service.make_localiser(
            lmap,
            sesame=sesame_params,
            temporal=temporal,
            start_xy_m=start_xy_m,
            start_radius_m=start_radius_m,
            camera=folder.meta.camera,
            odometry=odometry,
        )
        frames = (
            decode_gray(data, str(file))
            for file, (_row, data) in zip(folder.frame_files, iter_frame_images(folder), strict=True)
        )
        with stage_progress("localise") as report:
            estimates = loc_service.localise_frames(localiser, frames, [f.t_s for f in folder.frames], report)
        rows = loc_service.estimate_rows([f.frame for f in folder.frames], estimates)
        write_localisation_csv(out, rows)
    matched = sum(r.matched for r in rows)
    ms = float(np.median([e.ms for e in estimates])) if estimates else 0.0
    console.print(
        f"wrote {len(rows)} estimates against map version {number} to {out}: "
        f"{matched} matched ({100 * matched / max(len(rows), 1):.0f}%), {ms:.1f} ms per frame (median)"
    )


def _survey_point(text: str, option: str) -> tuple[float, float]:
    """'X,Y' in survey metres as two finite floats, or a :class:`BadInputError` naming ``option``."""
    parts = text.split(",")
    try:
        x_m, y_m = (float(p) for p in parts)
    except ValueError:
        raise BadInputError(f"expected 'X,Y' in survey metres, got {text!r}", field=option) from None
    if not (np.isfinite(x_m) and np.isfinite(y_m)):
        raise BadInputError(f"expected finite coordinates, got {text!r}", field=option)
    return x_m, y_m


def report_localisation(
    site: Annotated[str, typer.Argument(help="Site name.")],
    truth: Annotated[bool, typer.Option("--truth", help="Score against the drives' ground truth.")] = False,
    tolerance_m: Annotated[
        float, typer.Option("--tolerance-m", help="An estimate within this of the truth is right, metres.")
    ] = 15.0,
    out: Annotated[
        Path | None, typer.Option(help="Folder for the PNG and table (default: DATA_DIR/reports/SITE).")
    ] = None,
    map_version: Annotated[
        int | None, typer.Option("--map-version", help="Map version (default: latest).")
    ] = None,
    single_image_stride: Annotated[
        int,
        typer.Option("--single-image-stride", min=1, help="Score single-image methods on every n-th frame."),
    ] = 1,
    drive: Annotated[
        list[str] | None,
        typer.Option(
            "--drive", help="Only drives whose names match this glob (repeatable), e.g. 'loc-0[12]*'."
        ),
    ] = None,
    known_start: Annotated[
        bool,
        typer.Option(
            "--known-start",
            help="Start the HMM at each drive's true first position, as the SSLAM paper does (default: global start).",
        ),
    ] = False,
    method: Annotated[
        list[MethodName] | None,
        typer.Option("--method", help="Only these methods (repeatable)."),
    ] = None,
) -> None:
    """Precision-recall of SAD, SAD+SESAME, HMM+SAD and HMM+SESAME over the site's localisation drives."""
    storage = open_storage()
    with user_errors():
        if not truth:
            raise BadInputError("the localisation report needs ground truth: pass --truth", field="--truth")
        folder = out or get_settings().data_dir / "reports" / site
        with storage.db.session() as session:
            record = site_service.get_site(session, site)
            version = map_service.get_map_version(session, record, map_version)
            lmap = loc_service.load_version_localiser_map(session, storage.blobs, version)
            holistic = loc_service.load_version_localiser_map(session, storage.blobs, version, holistic=True)
            sesame_params = loc_service.sesame_params_of(version)
            drives = [
                d
                for d in loc_service.load_localisation_drives(session, storage.blobs, record)
                if d.truth_xy_m is not None and (not drive or any(fnmatch(d.name, g) for g in drive))
            ]
        with stage_progress("localisation report") as report:
            result = run_localisation_report(
                lmap,
                drives,
                sesame_params,
                tolerance_m=tolerance_m,
                out_dir=folder,
                single_image_stride=single_image_stride,
                holistic_map=holistic,
                known_start=known_start,
                progress=report,
                methods=None if method is None else [m.value for m in method],
            )
    console.print(result.table())
    fitted = result.calibration()
    if fitted is not None:
        knots = ", ".join(f"({x:.2f}, {p:.3f})" for x, p in fitted)
        console.print(f"calibration of the default method's raw confidence on these drives: ({knots})")
    console.print(f"figure: {result.figure}\ntable: {result.table_path}")
