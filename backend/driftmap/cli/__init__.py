"""The ``driftmap`` command line: thin typer commands that parse, call a service, and print."""

from __future__ import annotations

import logging
import sys
from typing import Annotated

import typer

from driftmap.cli import backup, camera, data, exports, localise, maps, replay, server, vpr, worker

app = typer.Typer(
    help="driftmap: camera-only mapping and localisation for underground mines.", no_args_is_help=True
)
app.add_typer(data.site_app, name="site")
app.add_typer(data.drive_app, name="drive")
app.add_typer(data.db_app, name="db")
maps.map_app.command("export")(exports.map_export)
app.add_typer(maps.map_app, name="map")
app.add_typer(exports.positions_app, name="positions")
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


@app.callback()
def main(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log debug messages.")] = False,
) -> None:
    """Configure logging for every command."""
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )


__all__ = ["app"]
