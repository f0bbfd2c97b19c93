"""Export commands: a map version (``map export``) and vehicle position history (``positions export``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from driftmap.cli.common import console, open_storage, user_errors
from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import write_poses_csv
from driftmap.formats.tables import write_text_atomic
from driftmap.services import exports as export_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services.exports import MapFormat, PositionFormat

positions_app = typer.Typer(help="Vehicle position history: export.", no_args_is_help=True)

SiteArgument = Annotated[str, typer.Argument(help="Site name.")]
OutOption = Annotated[Path | None, typer.Option("--out", help="File to write (with --format).")]


def map_export(
    site: SiteArgument,
    poses: Annotated[
        Path | None, typer.Option("--poses", help="Poses CSV to write (drive,frame,x,y,yaw).")
    ] = None,
    fmt: Annotated[
        MapFormat | None, typer.Option("--format", help="Format of --out (docs/formats.md, Exports).")
    ] = None,
    out: OutOption = None,
    version: Annotated[int | None, typer.Option(help="Map version (default: latest).")] = None,
    drive: Annotated[
        str | None, typer.Option("--drive", help="Only this mapping drive (needed by tum and kitti).")
    ] = None,
    nodes: Annotated[bool, typer.Option("--nodes", help="DXF: add the NODES layer.")] = False,
    closures: Annotated[
        bool, typer.Option("--closures", help="DXF: add the CLOSURES and CLOSURES-REJECTED layers.")
    ] = False,
) -> None:
    """Write a map version's optimised poses: --poses as the poses CSV, --format/--out as any export format."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        if poses is None and out is None:
            raise BadInputError("give --poses FILE, or --format F --out FILE", field="--out")
        if (fmt is None) != (out is None):
            raise BadInputError(
                "--format and --out go together", field="--format" if fmt is None else "--out"
            )
        if (nodes or closures) and fmt != "dxf":
            raise BadInputError("only the dxf format has node and closure layers", field="--format")
        record = site_service.get_site(session, site)
        found = map_service.get_map_version(session, record, version)
        exported = None  # made before anything is written, so a refused export writes nothing
        if fmt is not None:
            exported = export_service.export_map(
                session, storage.blobs, record, found, fmt, drive=drive, nodes=nodes, closures=closures
            )
        if poses is not None:
            rows = map_service.pose_rows(session, found)
            write_poses_csv(poses, rows)
            console.print(f"wrote {len(rows)} poses of map version {found.version} to {poses}")
        if exported is not None and out is not None:
            write_text_atomic(out, exported.text)
            console.print(f"wrote {exported.records} poses of map version {found.version} as {fmt} to {out}")


@positions_app.command("export")
def positions_export(
    site: SiteArgument,
    fmt: Annotated[PositionFormat, typer.Option("--format", help="File format (docs/formats.md, Exports).")],
    out: Annotated[Path, typer.Option("--out", help="File to write.")],
    vehicle: Annotated[
        str | None, typer.Option("--vehicle", help="Only this vehicle (default: every vehicle of the site).")
    ] = None,
    since: Annotated[
        float | None, typer.Option("--since", help="Earliest frame time t, seconds (vehicle clock).")
    ] = None,
    until: Annotated[float | None, typer.Option("--until", help="Latest frame time t, seconds.")] = None,
) -> None:
    """Write the position history of a site's vehicles (or one) over a time range."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        record = site_service.get_site(session, site)
        exported = export_service.export_positions(
            session, record, fmt, vehicle=vehicle, since_s=since, until_s=until
        )
        write_text_atomic(out, exported.text)
    console.print(f"wrote {exported.records} positions as {fmt} to {out}")
