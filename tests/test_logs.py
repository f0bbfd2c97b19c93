"""Log lines: JSON records parsed back (with the request id while a request is handled), the level each command
logs at by default and under DRIFTMAP_LOG_LEVEL, query strings kept out of the server's log configuration."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import time
from pathlib import Path

import pytest

from driftmap.cli.log_config import NoQueryStrings, log_config
from driftmap.config import Settings
from driftmap.logs import REQUEST_ID, JsonFormatter, RequestIdFilter
from tests.processes import driftmap_env, stop

WORKER_DEADLINE_S = 60.0  # a worker logs its start within this on a busy machine, seconds


def _record(message: str, *args: object, exc: bool = False) -> logging.LogRecord:
    info = None
    if exc:
        try:
            raise ValueError("broken")
        except ValueError:
            info = sys.exc_info()
    return logging.LogRecord("driftmap.test", logging.WARNING, __file__, 1, message, args, info)


class TestJsonFormatter:
    def test_a_record_is_one_json_object_with_the_request_id(self) -> None:
        token = REQUEST_ID.set("req-7")
        try:
            record = _record("frame %d of %s", 3, "lhd-1")
            RequestIdFilter().filter(record)
        finally:
            REQUEST_ID.reset(token)
        line = JsonFormatter().format(record)
        assert "\n" not in line
        parsed = json.loads(line)
        assert parsed == {
            "time": parsed["time"],
            "level": "WARNING",
            "logger": "driftmap.test",
            "message": "frame 3 of lhd-1",
            "request_id": "req-7",
        }
        assert parsed["time"].endswith("+00:00")

    def test_outside_a_request_no_id_and_a_traceback_stays_on_one_line(self) -> None:
        line = JsonFormatter().format(_record("failed", exc=True))
        parsed = json.loads(line)
        assert "request_id" not in parsed and "\n" not in line
        assert "ValueError: broken" in parsed["exc"]


class TestServerConfiguration:
    def test_level_and_format_from_the_settings(self) -> None:
        config = log_config(Settings(log_format="json"))
        assert {logger["level"] for logger in config["loggers"].values()} == {"INFO"}
        assert config["formatters"]["access"] == {"()": "driftmap.logs.JsonFormatter"}
        quiet = log_config(Settings(log_level="WARNING"))
        assert {logger["level"] for logger in quiet["loggers"].values()} == {"WARNING"}
        assert "JsonFormatter" not in json.dumps(quiet["formatters"])

    def test_access_lines_lose_their_query_strings(self) -> None:
        config = log_config(Settings())
        assert all("no_query_strings" in h["filters"] for h in config["handlers"].values())
        record = logging.LogRecord(
            "uvicorn.access", logging.INFO, __file__, 1, '%s - "%s %s HTTP/%s" %d',
            ("10.0.0.1:5000", "GET", "/api/live?token=dmv_1_secret&since=4", "1.1", 101), None,
        )  # fmt: skip
        assert NoQueryStrings().filter(record)
        assert record.getMessage() == '10.0.0.1:5000 - "GET /api/live HTTP/1.1" 101'


def _env(data_dir: Path, **settings: str) -> dict[str, str]:
    """A subprocess environment on its own SQLite file (whatever database the suite runs on)."""
    return driftmap_env(data_dir, f"sqlite:///{data_dir / 'driftmap.sqlite3'}", **settings)


def _stderr_of(command: list[str], env: dict[str, str]) -> list[str]:
    done = subprocess.run(
        [sys.executable, "-m", "driftmap", *command], env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    return [line for line in done.stderr.splitlines() if line.strip()]


class TestCommandLevels:
    def test_other_commands_log_warnings_unless_told(self, tmp_path: Path) -> None:
        """A first ``site list`` migrates a new database: alembic's INFO lines show only at INFO."""
        quiet = _stderr_of(["site", "list"], _env(tmp_path / "a", log_format="json"))
        assert not [line for line in quiet if json.loads(line)["level"] == "INFO"]
        told = _stderr_of(["site", "list"], _env(tmp_path / "b", log_format="json", log_level="INFO"))
        records = [json.loads(line) for line in told]  # every line is JSON
        assert any(r["level"] == "INFO" and r["logger"].startswith("alembic") for r in records)

    @pytest.mark.slow  # a real worker process
    def test_a_worker_logs_info_by_default(self, tmp_path: Path) -> None:
        env = _env(tmp_path / "data", log_format="json")
        env.pop("DRIFTMAP_REDIS_URL", None)
        log = tmp_path / "worker.log"
        with log.open("wb") as sink:
            worker = subprocess.Popen([sys.executable, "-m", "driftmap", "worker"], env=env, stderr=sink)
        try:
            deadline = time.monotonic() + WORKER_DEADLINE_S
            while "thread(s) on" not in log.read_text():  # the worker's start, logged at INFO
                assert worker.poll() is None and time.monotonic() < deadline, log.read_text()
                time.sleep(0.2)
        finally:
            stop(worker)
        records = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
        assert any(r["level"] == "INFO" and "thread(s) on" in r["message"] for r in records)
