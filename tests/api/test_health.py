"""``/api/health``: workers, the queue and Redis, on a real database and real (or absent) Redis servers."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from driftmap.api.app import create_app
from driftmap.config import Settings
from driftmap.services import supervision
from driftmap.store.db import Database
from driftmap.store.job_models import Job
from driftmap.store.models import utc_now
from driftmap.store.storage import Storage
from tests.processes import free_port
from tests.redis_server import running_redis


def _health(settings: Settings) -> tuple[int, dict[str, Any]]:
    """One health answer of a fresh app on ``settings`` (no lifespan: no localiser processes needed)."""
    app = create_app(settings)
    try:
        response = TestClient(app).get("/api/health")
    finally:
        app.state.storage.close()
    return response.status_code, response.json()


@pytest.fixture
def store(settings: Settings) -> Iterator[Storage]:
    opened = Storage.open(settings)
    yield opened
    opened.close()


class TestWorkers:
    def test_no_worker_is_degraded_and_names_the_part(self, settings: Settings) -> None:
        code, body = _health(settings)
        assert code == 200 and body["status"] == "degraded"
        assert body["workers"] == 0 and any("no job worker" in p for p in body["problems"])

    def test_a_worker_that_reported_makes_it_ok_until_it_is_stale(
        self, settings: Settings, store: Storage
    ) -> None:
        supervision.worker_seen(store.db, "host:1:")
        code, body = _health(settings)
        assert (code, body["status"], body["workers"], body["problems"]) == (200, "ok", 1, [])
        code, body = _health(settings.model_copy(update={"health_worker_stale_s": 0.0}))
        assert body["status"] == "degraded" and body["workers"] == 0
        supervision.worker_gone(store.db, "host:1:")
        assert _health(settings)[1]["workers"] == 0


class TestQueue:
    def test_jobs_waiting_while_nothing_moves_are_a_stalled_queue(
        self, settings: Settings, store: Storage
    ) -> None:
        supervision.worker_seen(store.db, "host:1:")
        with store.db.session() as session:
            session.add(Job(kind="site.simulate", args={}, created_at=utc_now() - timedelta(seconds=120)))
        _code, body = _health(settings.model_copy(update={"health_queue_stall_s": 60.0}))
        assert body["status"] == "degraded" and body["queue"]["stalled"] is True
        assert body["queue"]["queued"] == 1 and body["queue"]["oldest_queued_s"] >= 120
        assert any("queue is stalled" in p for p in body["problems"])

    def test_a_running_job_with_a_fresh_heartbeat_is_not_a_stall(
        self, settings: Settings, store: Storage
    ) -> None:
        supervision.worker_seen(store.db, "host:1:")
        old = utc_now() - timedelta(seconds=120)
        with store.db.session() as session:
            session.add(Job(kind="site.simulate", args={}, created_at=old))
            session.add(
                Job(kind="map.build", args={}, status="running", created_at=old, heartbeat_at=utc_now())
            )
        _code, body = _health(settings.model_copy(update={"health_queue_stall_s": 60.0}))
        assert body["status"] == "ok" and body["queue"] == {
            "queued": 1,
            "running": 1,
            "oldest_queued_s": pytest.approx(120, abs=30),
            "stalled": False,
        }


class TestRedis:
    def test_a_reachable_redis_is_ok(self, settings: Settings, store: Storage, tmp_path: Path) -> None:
        supervision.worker_seen(store.db, "host:1:")
        with running_redis(tmp_path) as url:
            code, body = _health(settings.model_copy(update={"redis_url": url}))
        assert (code, body["status"], body["redis"]) == (200, "ok", "ok")

    def test_an_unreachable_redis_is_degraded(self, settings: Settings, store: Storage) -> None:
        supervision.worker_seen(store.db, "host:1:")
        dead = f"redis://127.0.0.1:{free_port()}/0"  # nothing listens there
        code, body = _health(settings.model_copy(update={"redis_url": dead}))
        assert (code, body["status"], body["redis"]) == (200, "degraded", "unreachable")
        assert body["problems"] == ["Redis does not answer"]


class TestDatabase:
    def test_a_database_that_does_not_answer_is_503_down(self, settings: Settings) -> None:
        app = create_app(settings)
        storage: Storage = app.state.storage
        working = storage.db
        storage.db = Database(
            f"postgresql+psycopg://driftmap@127.0.0.1:{free_port()}/driftmap"
        )  # nothing there
        try:
            response = TestClient(app).get("/api/health")
        finally:
            storage.db.dispose()
            working.dispose()
        body = response.json()
        assert (response.status_code, body["status"], body["database"]) == (503, "down", "unreachable")
        assert body["problems"][0] == "the database does not answer"
