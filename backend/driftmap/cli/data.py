"""Commands over the stored data: simulate, sites, drives, the schema."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import typer
from rich.table import Table

from driftmap.cli.common import JsonOption, console, open_storage, print_json, stage_progress, user_errors
from driftmap.config import get_settings
from driftmap.errors import BadInputError
from driftmap.formats.site_crs import SiteCrs
from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.services.cameras import profiles as profile_service
from driftmap.store.storage import Storage

site_app = typer.Typer(help="Sites and their survey maps.", no_args_is_help=True)
drive_app = typer.Typer(help="Recorded drives: import, export, list.", no_args_is_help=True)
db_app = typer.Typer(help="The database schema.", no_args_is_help=True)
SizeName = Literal["tiny", "small", "medium", "large", "mine"]
"""The names of :data:`driftmap.sim.params.SIZES` (a test keeps them equal)."""
SimCamera = Literal["pinhole", "wide180"]
DriveKind = Literal["mapping", "localisation"]


def simulate(
    out: Annotated[
        Path, typer.Option("--out", help="Folder to write the site into (must be empty or absent).")
    ],
    seed: Annotated[int, typer.Option(help="Random seed; the same seed gives the same site.")] = 1,
    size: Annotated[
        SizeName, typer.Option(help="tiny, small (~400 m), medium (~1.5 km), large (~6 km) or mine (~20 km).")
    ] = "small",
    obscurants: Annotated[
        bool, typer.Option("--obscurants/--no-obscurants", help="Also write dust and water copies.")
    ] = True,
    camera: Annotated[
        SimCamera,
        typer.Option(
            help="pinhole (320x240, looking ahead) or wide180 (paper 000's 944x800 180-degree fisheye at the"
            " rear, with chessboard images to calibrate it in OUT/calibration)."
        ),
    ] = "pinhole",
) -> None:
    """Simulate a synthetic mine: survey.dxf, mapping and localisation drives with ground truth."""
    from driftmap.sim import simulate_site

    with user_errors(), stage_progress("simulating") as report:
        summary = simulate_site(
            out, seed=seed, size=size, obscurants=obscurants, progress=report, camera=camera
        )
    console.print(summary.describe())


@db_app.command("upgrade")
def db_upgrade() -> None:
    """Create or upgrade the database schema to the newest migration."""
    settings = get_settings()
    with user_errors():
        storage = Storage.open(settings)
        storage.close()
    console.print(f"schema up to date at {settings.resolved_database_url()}")


@site_app.command("create")
def site_create(
    name: Annotated[str, typer.Argument(help="Name of the new site.")],
    survey: Annotated[Path, typer.Option("--survey", help="Surveyed plan of the site (DXF, metres).")],
    drives: Annotated[
        Path | None, typer.Option("--drives", help="Also import every drive folder inside this folder.")
    ] = None,
    description: Annotated[str, typer.Option(help="Free text about the site.")] = "",
) -> None:
    """Create a site from its survey DXF (and optionally import a folder of drives)."""
    storage = open_storage()
    with user_errors():
        if not survey.is_file():
            raise BadInputError("no such file", file=survey, field="--survey")
        data = survey.read_bytes()
        with storage.blobs.batch() as batch, storage.db.session() as session:
            site = site_service.create_site(session, name, description)
            limits = site_service.survey_limits(get_settings())
            survey_map = site_service.add_survey_map(session, batch, site, data, str(survey), limits)
            layers = ", ".join(sorted(survey_map.layers))
        console.print(f"site {name!r} created; survey {survey.name}: layers {layers}")
        if drives is not None:
            for folder in drive_service.drive_folders_in(drives):
                _import_one(storage, name, folder)


def _import_one(
    storage: Storage,
    site_name: str,
    path: Path,
    *,
    calibration: Path | None = None,
    profile: str | None = None,
    name: str | None = None,
    kind: str = "mapping",
) -> None:
    with stage_progress(f"import {path.name}") as stage_report:

        def report(stage: str, fraction: float) -> None:
            stage_report(f"{stage} {path.name}", fraction)

        with storage.blobs.batch() as batch, storage.db.session() as session:
            site = site_service.get_site(session, site_name)
            camera = None
            if profile is not None:
                camera = profile_service.profile_camera(profile_service.find_profile(session, profile))
            drive = drive_service.import_drive(
                session,
                batch,
                site,
                path,
                progress=report,
                calibration=str(calibration) if calibration else None,
                camera=camera,
                name=name,
                kind=kind,
            )
            summary = f"drive {drive.name!r} ({drive.kind}): {drive.frame_count} frames"
    console.print(summary)


@drive_app.command("import")
def drive_import(
    site: Annotated[str, typer.Argument(help="Site name.")],
    path: Annotated[Path, typer.Argument(help="A drive folder (formats.md), or an mp4/avi video file.")],
    calibration: Annotated[
        Path | None,
        typer.Option(
            help="JSON file holding the camera block (and optional fps): a video's calibration, or for a"
            " folder one replacing its drive.json block."
        ),
    ] = None,
    profile: Annotated[
        str | None,
        typer.Option(help="A stored camera profile (name or id) the drive was recorded with, instead."),
    ] = None,
    name: Annotated[
        str | None, typer.Option(help="For a video: the drive's name (default: file stem).")
    ] = None,
    kind: Annotated[DriveKind, typer.Option(help="For a video: mapping or localisation.")] = "mapping",
) -> None:
    """Import one drive into a site; a failed import leaves nothing behind."""
    storage = open_storage()
    with user_errors():
        _import_one(storage, site, path, calibration=calibration, profile=profile, name=name, kind=kind)


@drive_app.command("export")
def drive_export(
    site: Annotated[str, typer.Argument(help="Site name.")],
    drive: Annotated[str, typer.Argument(help="Drive name.")],
    out: Annotated[Path, typer.Argument(help="Folder to write (must not exist or be empty).")],
) -> None:
    """Write a stored drive back as a drive folder in the formats.md layout."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        record = drive_service.export_drive(
            session, storage.blobs, site_service.get_site(session, site), drive, out
        )
        console.print(f"wrote {record.frame_count} frames of {record.name!r} to {out}")


@drive_app.command("list")
def drive_list(site: Annotated[str, typer.Argument(help="Site name.")], as_json: JsonOption = False) -> None:
    """List the drives of a site."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        rows = drive_service.list_drives(session, site_service.get_site(session, site))
        if as_json:
            print_json([_drive_json(row) for row in rows])
            return
        table = Table("id", "name", "kind", "frames", "fps", "duration s", "groundings", "truth")
        for row in rows:
            table.add_row(
                str(row.id),
                row.name,
                row.kind,
                str(row.frame_count),
                f"{row.fps:g}",
                f"{row.duration_s:.1f}",
                str(row.grounding_count),
                "yes" if row.has_truth else "no",
            )
    console.print(table)


def _drive_json(row: drive_service.DriveSummary) -> dict[str, object]:
    return {
        "id": row.id,
        "name": row.name,
        "kind": row.kind,
        "frames": row.frame_count,
        "fps": row.fps,
        "duration_s": row.duration_s,
        "groundings": row.grounding_count,
        "truth": row.has_truth,
    }


@site_app.command("list")
def site_list(as_json: JsonOption = False) -> None:
    """List the sites."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        if as_json:
            sites = site_service.list_sites(session)
            print_json(
                [
                    {
                        "id": s.id,
                        "name": s.name,
                        "survey_maps": len(s.survey_maps),
                        "drives": len(s.drives),
                        "created_at": s.created_at.isoformat(),
                    }
                    for s in sites
                ]
            )
            return
        table = Table("id", "name", "survey maps", "drives", "created")
        for site in site_service.list_sites(session):
            table.add_row(
                str(site.id),
                site.name,
                str(len(site.survey_maps)),
                str(len(site.drives)),
                f"{site.created_at:%Y-%m-%d}",
            )
    console.print(table)


@site_app.command("crs")
def site_crs(
    site: Annotated[str, typer.Argument(help="Site name or id.")],
    epsg: Annotated[
        int | None, typer.Option(help="EPSG code of the projected CRS (metres) the mine grid is in.")
    ] = None,
    false_origin: Annotated[
        str | None, typer.Option(help="E,N: the grid coordinates of the plane's origin, metres.")
    ] = None,
    rotation_deg: Annotated[
        float, typer.Option(help="Counter-clockwise angle from the plane's +x to the grid's east.")
    ] = 0.0,
    scale: Annotated[float, typer.Option(help="Grid metres per plane metre.")] = 1.0,
    clear: Annotated[bool, typer.Option("--clear", help="Back to plane metres only.")] = False,
) -> None:
    """Place a site's plane on the mine grid (and with --epsg on the Earth: GeoJSON and KML exports in WGS84)."""
    with user_errors():
        crs = None
        if not clear:
            east, north = 0.0, 0.0
            if false_origin is not None:
                try:
                    east, north = (float(v) for v in false_origin.split(","))
                except ValueError as exc:
                    raise BadInputError(
                        f"--false-origin must be E,N in metres, got {false_origin!r}", field="false_origin"
                    ) from exc
            crs = SiteCrs(epsg, east, north, rotation_deg, scale)
        storage = open_storage()
        with storage.db.session() as session:
            record = site_service.set_site_crs(session, site_service.get_site(session, site), crs)
            label = site_service.site_crs(record).export_label()
    console.print(f"site {site!r}: GeoJSON and KML exports in {label}")
