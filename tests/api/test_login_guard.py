"""Login throttling (in memory, and shared through a real Redis by two apps) and bounded password hashing."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from driftmap.api.app import create_app
from driftmap.config import Settings
from driftmap.services.login_guard import LoginGuard, LoginRefusedError, MemoryFailures, ThrottleRules
from tests.api.access_helpers import PASSWORD, Actors, make_actors
from tests.redis_server import running_redis

WINDOW_S = 1.5  # a short window, so that waiting it out is quick
DEADLINE_S = 10.0


def _throttled(settings: Settings, **limits: int) -> Settings:
    return settings.model_copy(update={"login_failure_window_s": WINDOW_S, **limits})


def _login(client: TestClient, username: str, password: str) -> int:
    return client.post("/api/auth/login", json={"username": username, "password": password}).status_code


@pytest.fixture
def actors(settings: Settings) -> Iterator[Actors]:
    made = make_actors(_throttled(settings, login_max_failures_per_user=3))
    yield made
    made.client.close()


class TestThrottle:
    def test_failures_of_one_user_give_429_with_retry_after_until_the_window_ends(
        self, actors: Actors
    ) -> None:
        assert [_login(actors.client, "viewer", "wrong-password") for _ in range(3)] == [401] * 3
        refused = actors.client.post("/api/auth/login", json={"username": "viewer", "password": PASSWORD})
        assert refused.status_code == 429 and "too many failed logins" in refused.json()["detail"]
        assert 1 <= int(refused.headers["retry-after"]) <= 2
        assert _login(actors.client, "surveyor", PASSWORD) == 200  # another user is not affected
        deadline = time.monotonic() + DEADLINE_S
        while _login(actors.client, "viewer", PASSWORD) != 200:
            assert time.monotonic() < deadline, "still throttled after the window"
            time.sleep(0.2)

    def test_a_successful_login_clears_the_user_count(self, actors: Actors) -> None:
        for _ in range(2):
            assert _login(actors.client, "viewer", "wrong-password") == 401
        assert _login(actors.client, "viewer", PASSWORD) == 200
        assert [_login(actors.client, "viewer", "wrong-password") for _ in range(3)] == [401] * 3

    def test_failures_from_one_address_over_many_names_give_429(self, settings: Settings) -> None:
        made = make_actors(_throttled(settings, login_max_failures_per_address=4))
        try:
            answers = [_login(made.client, f"nobody-{k}", "wrong-password") for k in range(5)]
            assert answers == [401] * 4 + [429]
            assert _login(made.client, "viewer", PASSWORD) == 429  # the address is refused, whoever it names
        finally:
            made.client.close()


class TestSharedThroughRedis:
    def test_two_api_processes_share_the_counts(self, settings: Settings, tmp_path: Path) -> None:
        with running_redis(tmp_path) as url:
            shared = _throttled(settings, login_max_failures_per_user=2).model_copy(update={"redis_url": url})
            first = make_actors(shared)
            second = TestClient(create_app(shared))  # another API process on the same database and Redis
            try:
                assert [_login(first.client, "viewer", "wrong-password") for _ in range(2)] == [401, 401]
                refused = second.post("/api/auth/login", json={"username": "viewer", "password": PASSWORD})
                assert refused.status_code == 429 and int(refused.headers["retry-after"]) >= 1
                deadline = time.monotonic() + DEADLINE_S
                while _login(second, "viewer", PASSWORD) != 200:
                    assert time.monotonic() < deadline, "still throttled after the window"
                    time.sleep(0.2)
            finally:
                first.client.close()
                second.close()


class TestHashing:
    def test_at_most_the_configured_hashes_run_at_once_and_the_rest_wait_or_are_refused(self) -> None:
        guard = LoginGuard(ThrottleRules(10, 10, 60.0), MemoryFailures(), concurrency=2, waiting_max=3)
        lock = threading.Lock()
        running, most = 0, 0

        def work() -> str:
            nonlocal running, most
            with lock:
                running += 1
                most = max(most, running)
            time.sleep(0.05)
            with lock:
                running -= 1
            return "done"

        async def many() -> list[str]:
            async def one() -> str:
                try:
                    return await guard.hashing(work)
                except LoginRefusedError as exc:
                    return f"refused {exc.retry_after_s}"

            return await asyncio.gather(*(one() for _ in range(10)))

        answers = asyncio.run(many())
        assert sorted(answers) == ["done"] * 5 + ["refused 1"] * 5
        assert most == 2
