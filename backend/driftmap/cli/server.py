"""``driftmap serve`` (the API and, on the embedded default, one job worker beside it) and ``driftmap user``.

``driftmap serve --workers N`` runs N API processes on one port (uvicorn's workers, each building the app
with :func:`driftmap.api.app.create_app`); they share live state through Redis, so N > 1 needs
``DRIFTMAP_REDIS_URL`` (and then no job worker is started beside them: run ``driftmap worker``).
The job worker beside a single API process is supervised (:mod:`driftmap.cli.supervisor`): restarted when
it dies, stopped when the server stops or dies. The access log shows paths without query strings
(:mod:`driftmap.cli.log_config`).
"""

from __future__ import annotations

import inspect
import logging
import signal
import sys
from collections.abc import Callable
from types import FrameType
from typing import Annotated, Any, Literal

import typer

from driftmap.cli.common import JsonOption, console, open_storage, print_json, user_errors
from driftmap.cli.log_config import log_config
from driftmap.cli.supervisor import WorkerSupervisor
from driftmap.config import get_settings
from driftmap.services import users as user_service

log = logging.getLogger(__name__)
user_app = typer.Typer(help="Users of the server and their roles.", no_args_is_help=True)
API_PROCESS_HEALTHCHECK_S = 60
"""How long uvicorn waits for an API process to answer its health ping before it kills and restarts it, seconds.
Its default (5 s) is shorter than a fresh process takes to import driftmap on a busy machine, so the processes
were killed over and over before serving."""


@user_app.command("add")
def user_add(
    name: Annotated[str, typer.Argument(help="The user name to log in with.")],
    role: Annotated[
        Literal["admin", "surveyor", "viewer"],
        typer.Option(help="admin, surveyor (groundings, imports, builds) or viewer."),
    ],
    password_stdin: Annotated[
        bool, typer.Option("--password-stdin", help="Read the password from the first line of stdin.")
    ] = False,
) -> None:
    """Create a user (asks for the password unless --password-stdin)."""
    if password_stdin:
        password = sys.stdin.readline().rstrip("\r\n")
    else:
        password = typer.prompt("Password", hide_input=True, confirmation_prompt=True)
    with user_errors():
        storage = open_storage()
        try:
            with storage.db.session() as session:
                user = user_service.create_user(session, name, password, role)
                console.print(f"user {user.username!r} ({user.role}) created with id {user.id}")
        finally:
            storage.close()


@user_app.command("list")
def user_list(as_json: JsonOption = False) -> None:
    """Every user with its role."""
    storage = open_storage()
    try:
        with storage.db.session() as session:
            users = user_service.list_users(session)
            if as_json:
                print_json([{"id": u.id, "username": u.username, "role": u.role} for u in users])
                return
            for user in users:
                console.print(f"{user.id}\t{user.username}\t{user.role}")
    finally:
        storage.close()


def _healthcheck_option(run: Callable[..., None]) -> dict[str, Any]:
    """``timeout_worker_healthcheck`` for uvicorn versions whose supervisor pings its processes (0.30 on)."""
    if "timeout_worker_healthcheck" in inspect.signature(run).parameters:
        return {"timeout_worker_healthcheck": API_PROCESS_HEALTHCHECK_S}
    return {}


def _exit_on_sigterm(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)


def serve(
    host: Annotated[str, typer.Option(help="Interface to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port.")] = 8000,
    worker: Annotated[
        bool,
        typer.Option("--worker/--no-worker", help="Start one job worker beside the API (embedded queue)."),
    ] = True,
    workers: Annotated[
        int,
        typer.Option(
            "--workers", min=1, help="API processes on the port; more than one needs DRIFTMAP_REDIS_URL."
        ),
    ] = 1,
) -> None:
    """Run the web server; without DRIFTMAP_REDIS_URL also one job worker process beside it."""
    import uvicorn

    from driftmap.api.app import create_app

    settings = get_settings()
    if workers > 1:
        if settings.redis_url is None:
            raise typer.BadParameter(
                "several API processes share watchers and latest frames through Redis: set DRIFTMAP_REDIS_URL",
                param_hint="--workers",
            )
        with user_errors():
            open_storage().close()  # upgrade the schema once, before the processes start
        uvicorn.run(
            "driftmap.api.app:create_app",
            factory=True,
            workers=workers,
            host=host,
            port=port,
            log_level="info",
            log_config=log_config(settings),
            ws_max_size=2 * settings.max_frame_bytes,
            **_healthcheck_option(uvicorn.run),
        )
        return
    with user_errors():
        app = create_app(settings)  # opens and upgrades the database before the worker starts
    supervisor = WorkerSupervisor() if worker and settings.redis_url is None else None
    if supervisor is not None:
        supervisor.start()
    # uvicorn re-raises SIGTERM after its graceful shutdown; turn it into SystemExit so the worker is stopped.
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    try:
        uvicorn.run(
            app,
            host=host,
            port=port,
            log_level="info",
            log_config=log_config(settings),
            ws_max_size=2 * settings.max_frame_bytes,
        )
    except KeyboardInterrupt:
        pass
    finally:
        if supervisor is not None:
            supervisor.stop()
