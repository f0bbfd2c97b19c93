"""``driftmap replay``: recorded drives as live vehicles, posted to a server's frame endpoint at their pace.

With ``--serve`` the command also starts ``driftmap serve`` (its output goes to a log file) and stops it
again when the replay ends: Ctrl-C (or SIGTERM) stops the vehicles, then the server and its worker. This is
what ``make demo`` runs.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import urllib.parse
from pathlib import Path
from types import FrameType
from typing import Annotated

import typer
from rich.text import Text

from driftmap.cli.common import console, err_console, user_errors
from driftmap.config import get_settings
from driftmap.errors import BadInputError
from driftmap.services import vehicle_replay as replay_service
from driftmap.services.vehicle_replay import ApiClient, ReplayStats

SERVER_START_DEADLINE_S = 120.0
SERVER_STOP_TIMEOUT_S = 60.0
LOG_FILE_MODE = 0o600


def _start_server(url: str, log: Path) -> subprocess.Popen[bytes]:
    """``driftmap serve`` on the host and port of ``url``, in its own session (our Ctrl-C stops it in order)."""
    parsed = urllib.parse.urlsplit(url)
    if parsed.scheme != "http" or parsed.hostname is None:
        raise BadInputError(f"--serve needs an http://HOST:PORT url, got {url!r}", field="--url")
    log.parent.mkdir(parents=True, exist_ok=True)
    # readable by its owner only: a server log names users and vehicles, and may hold what clients sent
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, LOG_FILE_MODE)
    os.fchmod(fd, LOG_FILE_MODE)  # an existing log too
    with os.fdopen(fd, "ab") as sink:
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "driftmap",
                "serve",
                "--host",
                parsed.hostname,
                "--port",
                str(parsed.port or 80),
            ],
            stdout=sink,
            stderr=sink,
            start_new_session=True,
        )
    err_console.print(f"driftmap: server process {process.pid} starting (log: {log})")
    return process


def _stop_server(process: subprocess.Popen[bytes]) -> None:
    """SIGTERM (the server stops its worker and localiser processes), then kill if it does not stop in time."""
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(SERVER_STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    err_console.print(f"driftmap: server process {process.pid} stopped")


def _interrupt_on_sigterm(_signum: int, _frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def replay(
    site: Annotated[str, typer.Argument(help="Name of the site the vehicles drive in (it needs a map).")],
    drives: Annotated[list[Path], typer.Argument(help="Drive folders; each becomes a vehicle of its name.")],
    url: Annotated[str, typer.Option(help="The server's base URL.")] = "http://127.0.0.1:8000",
    user: Annotated[
        str, typer.Option(help="An admin user (creates vehicles, issues their tokens).")
    ] = "admin",
    password_stdin: Annotated[
        bool, typer.Option("--password-stdin", help="Read the password from the first line of stdin.")
    ] = False,
    serve: Annotated[
        bool, typer.Option("--serve", help="Start `driftmap serve` on the URL's host and port first.")
    ] = False,
    server_log: Annotated[
        Path | None, typer.Option(help="Where --serve writes the server's output [<data dir>/serve.log].")
    ] = None,
    once: Annotated[bool, typer.Option("--once", help="Play each drive once instead of looping.")] = False,
    max_frames: Annotated[
        int | None, typer.Option(min=1, help="Stop each vehicle after sending this many frames.")
    ] = None,
    speed: Annotated[float, typer.Option(min=0.01, help="Time-lapse factor (2: twice as fast).")] = 1.0,
    status_every: Annotated[float, typer.Option(help="Seconds between two status reports.")] = 10.0,
    show_login: Annotated[
        bool, typer.Option("--show-login", help="Print the UI address with the user name and password.")
    ] = False,
) -> None:
    """Replay recorded drives as live vehicles through POST /api/vehicles/{id}/frames, until Ctrl-C."""
    password = (
        sys.stdin.readline().rstrip("\r\n") if password_stdin else typer.prompt("Password", hide_input=True)
    )
    # Ctrl-C and SIGTERM end the replay in order (vehicles, then the server), even when started from a
    # shell that ignores SIGINT for background commands
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _interrupt_on_sigterm)
    server: subprocess.Popen[bytes] | None = None
    stop = threading.Event()
    threads: list[threading.Thread] = []
    stats: list[ReplayStats] = []
    try:
        with user_errors():
            recorded = [replay_service.load_drive(d) for d in drives]
            client = ApiClient(url)
            if serve:
                server = _start_server(url, server_log or get_settings().data_dir / "serve.log")
                running = server
                replay_service.wait_until_healthy(
                    client, SERVER_START_DEADLINE_S, lambda: running.poll() is None
                )
            client.login(user, password)
            site_id = replay_service.site_id_by_name(client, site)
            for drive in recorded:
                vehicle_id, token = replay_service.vehicle_with_token(
                    client, site_id, drive.name, drive.camera
                )
                vehicle = ReplayStats(drive.name, vehicle_id)
                stats.append(vehicle)
                threads.append(
                    threading.Thread(
                        target=replay_service.replay_vehicle,
                        args=(client, vehicle, token, drive, stop),
                        kwargs={"loop": not once, "max_frames": max_frames, "speed": speed},
                        name=f"replay-{drive.name}",
                        daemon=True,
                    )
                )
        if show_login:
            console.print(
                Text(f"driftmap UI: {url}  log in as {user!r} with password {password!r}", style="bold"),
                soft_wrap=True,
            )
        names = ", ".join(
            f"{s.vehicle} ({len(d.times_s)} frames, {d.duration_s:.0f} s)"
            for s, d in zip(stats, recorded, strict=True)
        )
        console.print(
            f"replaying {names} on site {site!r} at {speed:g}x{'' if once else ', looping'}; Ctrl-C stops",
            soft_wrap=True,
        )
        for thread in threads:
            thread.start()
        next_report = time.monotonic() + status_every
        while any(t.is_alive() for t in threads):
            for thread in threads:
                thread.join(0.2)
            if time.monotonic() >= next_report:
                next_report += status_every
                for vehicle in stats:
                    console.print(replay_service.describe(vehicle), soft_wrap=True, markup=False)
    except KeyboardInterrupt:
        err_console.print("driftmap: stopping the replay")
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C does not cut the orderly stop short
        stop.set()
        for thread in threads:
            thread.join(10.0)
        for vehicle in stats:
            console.print(replay_service.describe(vehicle), soft_wrap=True, markup=False)
        if server is not None:
            _stop_server(server)
