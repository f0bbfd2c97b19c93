"""A private PostgreSQL server for tests: a throw-away cluster on a free loopback port.

Debian's ``postgresql`` package provides the binaries (``make test`` installs it); the cluster lives in a
temporary directory, trusts local connections, and skips durability (fsync off) because it is deleted after
the run. PostgreSQL refuses to run as root, so under root the server runs as the ``postgres`` system user.

Each test that needs a database gets a fresh one copied from a migrated template (:meth:`fresh_database`),
so a test never sees another test's rows and the migrations run once per session, not once per test.
"""

from __future__ import annotations

import glob
import os
import shutil
import signal
import subprocess
import tempfile
import time
import uuid
from pathlib import Path

import psycopg
from alembic.config import Config
from alembic.script import ScriptDirectory
from psycopg import sql

from tests.processes import free_port, stop

USER = "driftmap"
TEMPLATE = "driftmap_template"
STOP_DEADLINE_S = 30.0


def revision_before_partitioning(config: Config) -> str:
    """The Alembic revision just before the one that partitions the positions table (its plain-table schema)."""
    for script in ScriptDirectory.from_config(config).walk_revisions():
        if script.path.endswith("_partitioned_positions.py") and isinstance(script.down_revision, str):
            return script.down_revision
    raise LookupError("no migration *_partitioned_positions.py")


_active: PostgresServer | None = None


def active_server() -> PostgresServer | None:
    """The server the tests' databases are on in a ``--database postgresql`` run, else None."""
    return _active


def set_active_server(server: PostgresServer | None) -> None:
    """Record the server of a ``--database postgresql`` run (the session fixture does)."""
    global _active
    _active = server


def postgres_bin_dir() -> Path | None:
    """Directory of ``initdb`` and ``postgres``, or None when PostgreSQL is not installed."""
    pg_config = shutil.which("pg_config")
    if pg_config:
        found = Path(subprocess.run([pg_config, "--bindir"], capture_output=True, text=True).stdout.strip())
        if (found / "initdb").is_file():
            return found
    candidates = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    return Path(candidates[-1]).parent if candidates else None


class PostgresServer:
    """One ``postgres`` process serving a cluster in a new temporary directory (removed by :meth:`stop`).

    The directory is made directly under the system temporary directory: pytest's own temporary directories
    are private to their user, and under root the server runs as ``postgres``.

    Args:
        bin_dir: where ``initdb`` and ``postgres`` are.
    """

    def __init__(self, bin_dir: Path) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="driftmap-pg-"))
        self.bin_dir = bin_dir
        self.port = free_port()
        self.log = self.root / "postgres.log"
        self._process: subprocess.Popen[bytes] | None = None
        self._as_user: list[str] = []
        if os.geteuid() == 0:  # initdb and postgres refuse root
            self._as_user = ["setpriv", "--reuid=postgres", "--regid=postgres", "--clear-groups"]
            shutil.chown(self.root, "postgres")
        if shutil.which("setpriv"):  # the server stops with the test process, even when that is killed
            self._as_user = [*(self._as_user or ["setpriv"]), "--pdeathsig=INT"]  # INT: fast shutdown

    @property
    def pid(self) -> int | None:
        """The server's process id while it runs (its backends are its children)."""
        return self._process.pid if self._process is not None else None

    def url(self, database: str = "postgres") -> str:
        """SQLAlchemy URL of ``database`` on this server (psycopg 3 driver)."""
        return f"postgresql+psycopg://{USER}@127.0.0.1:{self.port}/{database}"

    def _connect(self, database: str = "postgres") -> psycopg.Connection[tuple[object, ...]]:
        return psycopg.connect(
            host="127.0.0.1", port=self.port, user=USER, dbname=database, autocommit=True, connect_timeout=5
        )

    def start(self, deadline_s: float = 60.0) -> None:
        """Create the cluster and start the server; returns when it accepts connections."""
        data = self.root / "cluster"
        subprocess.run(
            [*self._as_user, str(self.bin_dir / "initdb"), "-D", str(data), "-U", USER, "--auth=trust",
             "-E", "UTF8", "--no-locale", "--no-sync"],
            check=True, capture_output=True,
        )  # fmt: skip
        with self.log.open("wb") as log:
            self._process = subprocess.Popen(
                [*self._as_user, str(self.bin_dir / "postgres"), "-D", str(data), "-p", str(self.port),
                 "-k", str(self.root), "-c", "listen_addresses=127.0.0.1", "-c", "fsync=off",
                 "-c", "synchronous_commit=off", "-c", "full_page_writes=off", "-c", "max_connections=400"],
                stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
            )  # fmt: skip
        deadline = time.monotonic() + deadline_s
        while True:
            assert self._process.poll() is None, f"postgres exited:\n{self.log.read_text()}"
            try:
                with self._connect():
                    return
            except psycopg.OperationalError:
                assert time.monotonic() < deadline, f"postgres did not start:\n{self.log.read_text()}"
                time.sleep(0.1)

    def create_database(self, name: str, template: str | None = None) -> str:
        """Create database ``name`` (a copy of ``template`` when given); returns its URL."""
        with self._connect() as connection:
            statement = sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name))
            if template is not None:
                statement += sql.SQL(" TEMPLATE {}").format(sql.Identifier(template))
            connection.execute(statement)
        return self.url(name)

    def drop_database(self, name: str) -> None:
        """Drop database ``name``, ending whatever connections still use it."""
        with self._connect() as connection:
            connection.execute(
                sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(name))
            )

    def prepare_template(self) -> None:
        """Create the migrated template database the fresh test databases are copied from."""
        from driftmap.store.db import Database

        database = Database(self.create_database(TEMPLATE))
        try:
            database.upgrade()
        finally:
            database.dispose()

    def fresh_database(self) -> tuple[str, str]:
        """A new database with the current schema: ``(name, url)``."""
        name = f"t_{uuid.uuid4().hex[:12]}"
        return name, self.create_database(name, template=TEMPLATE)

    def stop(self) -> None:
        """Stop the server (fast shutdown: sessions still open are ended, not waited for) and wait for it."""
        if self._process is not None:
            self._process.send_signal(signal.SIGINT)  # SIGTERM would wait for every client to disconnect
            try:
                self._process.wait(STOP_DEADLINE_S)
            except subprocess.TimeoutExpired:
                stop(self._process)
            self._process = None
        shutil.rmtree(self.root, ignore_errors=True)

    def snapshot(self, template: str = TEMPLATE) -> tuple[str, str]:
        """A new database that lives until the server stops (not one test): ``(name, url)``; a copy of
        ``template`` (by default the empty migrated schema)."""
        name = f"s_{uuid.uuid4().hex[:12]}"
        return name, self.create_database(name, template=template)

    def restore_current(self, snapshot: str) -> None:
        """Make this test's database (``DRIFTMAP_DATABASE_URL``) a copy of database ``snapshot``."""
        current = os.environ["DRIFTMAP_DATABASE_URL"].rsplit("/", 1)[1]
        self.drop_database(current)
        self.create_database(current, template=snapshot)
