"""``driftmap groundings``: a site's survey control file (``drive,frame,station,x,y,enabled``, formats.md)
out of the store and back in (an import replaces all the site's groundings once the whole file checks), and a
map version's residuals CSV."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from driftmap.cli.common import console, open_storage, user_errors
from driftmap.errors import BadInputError
from driftmap.formats.tables import write_text_atomic
from driftmap.services import groundings as grounding_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services.residuals import residuals_csv

groundings_app = typer.Typer(help="Survey control: a site's groundings as one CSV.", no_args_is_help=True)
SiteArg = Annotated[str, typer.Argument(help="Site name.")]


@groundings_app.command("export")
def groundings_export(
    site: SiteArg,
    out: Annotated[
        Path, typer.Option("--out", help="Control file to write (drive,frame,station,x,y,enabled).")
    ],
) -> None:
    """Write the site's groundings as its survey control file."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        record = site_service.get_site(session, site)
        text = grounding_service.export_site_csv(session, record.id)
        write_text_atomic(out, text)
    console.print(f"wrote {text.count(chr(10)) - 1} groundings of {site!r} to {out}")


@groundings_app.command("import")
def groundings_import(
    site: SiteArg,
    file: Annotated[Path, typer.Argument(help="Control file (drive,frame,station,x,y,enabled).")],
) -> None:
    """Replace all the site's groundings with a control file; a bad row names its line and field."""
    storage = open_storage()
    with user_errors():
        if not file.is_file():
            raise BadInputError("no such file", file=file)
        data = file.read_bytes()
        with storage.db.session() as session:
            record = site_service.get_site(session, site)
            count = grounding_service.import_site_csv(session, record.id, data, str(file), "cli")
    console.print(f"imported {count} groundings into {site!r}")


@groundings_app.command("residuals")
def groundings_residuals(
    site: SiteArg,
    out: Annotated[
        Path, typer.Option("--out", help="CSV to write (drive,frame,station,x,y,residual_m,enabled).")
    ],
    version: Annotated[int | None, typer.Option(help="Map version (default: latest).")] = None,
) -> None:
    """Write a map version's residuals at the groundings it was built with (formats.md, Residuals CSV)."""
    storage = open_storage()
    with user_errors(), storage.db.session() as session:
        record = map_service.get_map_version(session, site_service.get_site(session, site), version)
        text = residuals_csv(session, record)
        write_text_atomic(out, text)
    console.print(
        f"wrote {len(text.splitlines()) - 1} residuals of map version {record.version} of {site!r} to {out}"
    )
