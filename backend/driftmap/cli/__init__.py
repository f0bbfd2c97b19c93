"""The ``driftmap`` command line: thin typer commands that parse, call a service, and print."""

from __future__ import annotations

import logging
import sys
from typing import Annotated

import typer
from pydantic import ValidationError

from driftmap.cli import (
    backup,
    camera,
    data,
    exports,
    groundings,
    localise,
    maps,
    replay,
    server,
    vpr,
    worker,
)
from driftmap.cli.common import err_console
from driftmap.config import get_settings
from driftmap.logs import TEXT_FORMAT, JsonFormatter, RequestIdFilter

app = typer.Typer(
    help="driftmap: camera-only mapping and localisation for underground mines.", no_args_is_help=True
)
app.add_typer(data.site_app, name="site")
app.add_typer(data.drive_app, name="drive")
app.add_typer(data.db_app, name="db")
maps.map_app.command("export")(exports.map_export)
app.add_typer(maps.map_app, name="map")
app.add_typer(exports.positions_app, name="positions")
app.add_typer(groundings.groundings_app, name="groundings")
maps.report_app.command("localisation")(localise.report_localisation)
app.add_typer(maps.report_app, name="report")
app.add_typer(vpr.vpr_app, name="vpr")
app.add_typer(camera.camera_app, name="camera")
app.add_typer(server.user_app, name="user")
app.command()(server.serve)
app.command()(worker.worker)
app.command()(replay.replay)
app.command()(data.simulate)
app.command()(backup.backup)
app.command()(backup.restore)
app.command()(maps.odometry)
app.command()(localise.localise)


_SERVICES = ("serve", "worker")
"""Commands that run for long: they log at INFO unless DRIFTMAP_LOG_LEVEL says otherwise."""


@app.callback()
def main(
    ctx: typer.Context,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log debug messages.")] = False,
) -> None:
    """Configure logging for every command (DRIFTMAP_LOG_LEVEL, DRIFTMAP_LOG_FORMAT; docs/operations.md)."""
    try:
        settings = get_settings()
    except ValidationError as exc:  # a DRIFTMAP_* variable that does not parse: name it, no traceback
        first = exc.errors()[0]
        variable = "DRIFTMAP_" + str(first["loc"][0]).upper() if first["loc"] else "DRIFTMAP_*"
        err_console.print(f"error: {variable}: {first['msg']}", soft_wrap=True)
        raise typer.Exit(2) from None
    default = "INFO" if ctx.invoked_subcommand in _SERVICES else "WARNING"
    handler = logging.StreamHandler(sys.stderr)
    handler.addFilter(RequestIdFilter())
    json_lines = settings.log_format == "json"
    handler.setFormatter(JsonFormatter() if json_lines else logging.Formatter(TEXT_FORMAT))
    logging.basicConfig(level="DEBUG" if verbose else settings.log_level or default, handlers=[handler])


__all__ = ["app"]
