"""What a login may cost: failed logins are throttled, password hashing is bounded.

Throttling: failed logins are counted per user name and per client address over a fixed window
(``login_failure_window_s``); once a count reaches its limit (``login_max_failures_per_user``,
``login_max_failures_per_address``) further logins of that name or address are refused with
:class:`LoginRefusedError` (HTTP 429 with ``Retry-After``) *before* any password is hashed, until the window
ends. A successful login clears its user name's count. The counts live in Redis when ``DRIFTMAP_REDIS_URL``
is set (shared by every API process), else in the API process's memory (one process then serves the API).
Counter keys hold a SHA-256 of the name, so long or many names cost bounded memory.

Hashing: argon2id takes 64 MiB and tens of milliseconds of CPU per password; at most
``login_hash_concurrency`` are computed at once in dedicated threads (not the request thread pool, which
keeps serving other routes), at most ``login_waiting_max`` logins wait for one, and a login beyond that is
refused at once.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TypeVar

import anyio
import anyio.to_thread
import redis.asyncio as aioredis
from redis.exceptions import RedisError

from driftmap.config import Settings

log = logging.getLogger(__name__)
T = TypeVar("T")
MEMORY_MAX_KEYS = 100_000
"""Most counters the in-memory store keeps; beyond it the oldest are dropped."""


class LoginRefusedError(Exception):
    """A login refused without looking at its password; retry after ``retry_after_s`` seconds."""

    def __init__(self, message: str, retry_after_s: float) -> None:
        super().__init__(message)
        self.retry_after_s = max(1, math.ceil(retry_after_s))


class FailureStore(Protocol):
    """Failure counters with a fixed window each."""

    async def count(self, key: str) -> tuple[int, float]:
        """(failures, seconds until the window ends) of ``key``; (0, 0) when none."""
        ...

    async def add(self, key: str, window_s: float) -> None:
        """One more failure of ``key``; a new window starts at the first."""
        ...

    async def clear(self, key: str) -> None:
        """Forget ``key``'s failures."""
        ...


class MemoryFailures:
    """Counters in this process's memory (single API process without Redis)."""

    def __init__(self, max_keys: int = MEMORY_MAX_KEYS) -> None:
        self.max_keys = max_keys
        self._counts: dict[str, tuple[int, float]] = {}  # key -> (failures, monotonic end of window)

    async def count(self, key: str) -> tuple[int, float]:
        failures, end = self._counts.get(key, (0, 0.0))
        left = end - time.monotonic()
        return (failures, left) if left > 0 else (0, 0.0)

    async def add(self, key: str, window_s: float) -> None:
        failures, left = await self.count(key)
        end = time.monotonic() + (left if failures else window_s)
        self._counts.pop(key, None)  # re-inserted last: the dict stays ordered oldest first
        if len(self._counts) >= self.max_keys:
            now = time.monotonic()
            self._counts = {k: v for k, v in self._counts.items() if v[1] > now}
            while len(self._counts) >= self.max_keys:
                del self._counts[next(iter(self._counts))]
        self._counts[key] = (failures + 1, end)

    async def clear(self, key: str) -> None:
        self._counts.pop(key, None)


class RedisFailures:
    """Counters in Redis (shared by every API process); the key's own expiry is the window."""

    def __init__(self, url: str, prefix: str = "driftmap:login:") -> None:
        self.url = url
        self.prefix = prefix
        self._client: aioredis.Redis | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    def _redis(self) -> aioredis.Redis:
        loop = asyncio.get_running_loop()
        if self._client is None or self._loop is not loop:  # a client belongs to one event loop
            self._client, self._loop = aioredis.Redis.from_url(self.url, socket_timeout=2.0), loop
        return self._client

    async def count(self, key: str) -> tuple[int, float]:
        async with self._redis().pipeline(transaction=False) as pipe:
            pipe.get(self.prefix + key)
            pipe.pttl(self.prefix + key)
            value, ttl_ms = await pipe.execute()
        return (int(value), ttl_ms / 1000.0) if value is not None and ttl_ms > 0 else (0, 0.0)

    async def add(self, key: str, window_s: float) -> None:
        async with self._redis().pipeline(transaction=True) as pipe:
            pipe.set(self.prefix + key, 0, px=max(1, int(window_s * 1000)), nx=True)
            pipe.incr(self.prefix + key)
            await pipe.execute()

    async def clear(self, key: str) -> None:
        await self._redis().delete(self.prefix + key)


@dataclass(frozen=True)
class ThrottleRules:
    """Limits of failed logins (see the module docstring)."""

    per_user: int
    per_address: int
    window_s: float


def _key(kind: str, value: str) -> str:
    return f"{kind}:{hashlib.sha256(value.encode('utf-8', 'surrogatepass')).hexdigest()}"


class LoginGuard:
    """Throttles failed logins and bounds concurrent password hashing for one API process."""

    def __init__(self, rules: ThrottleRules, store: FailureStore, concurrency: int, waiting_max: int) -> None:
        self.rules = rules
        self.store = store
        self.concurrency = max(1, concurrency)
        self.waiting_max = max(0, waiting_max)
        self._in_flight = 0
        self._limiter: anyio.CapacityLimiter | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    @classmethod
    def from_settings(cls, settings: Settings) -> LoginGuard:
        """The guard of ``settings``: counters in Redis when configured, else in memory."""
        rules = ThrottleRules(
            settings.login_max_failures_per_user,
            settings.login_max_failures_per_address,
            settings.login_failure_window_s,
        )
        store: FailureStore = RedisFailures(settings.redis_url) if settings.redis_url else MemoryFailures()
        return cls(rules, store, settings.login_hash_concurrency, settings.login_waiting_max)

    def _keys(self, username: str, address: str) -> list[tuple[str, int, str]]:
        return [
            (_key("user", username.strip()), self.rules.per_user, "this user name"),
            (_key("addr", address), self.rules.per_address, "this address"),
        ]

    async def check(self, username: str, address: str) -> None:
        """Raise :class:`LoginRefusedError` when ``username`` or ``address`` used up its failed logins."""
        for key, limit, what in self._keys(username, address):
            try:
                failures, left_s = await self.store.count(key)
            except RedisError:
                log.warning("login throttle: Redis unreachable; not throttling", exc_info=True)
                return
            if failures >= limit:
                raise LoginRefusedError(
                    f"too many failed logins for {what}; try again in {math.ceil(left_s)} s", left_s
                )

    async def failed(self, username: str, address: str) -> None:
        """Count a failed login of ``username`` from ``address``."""
        try:
            for key, _limit, _what in self._keys(username, address):
                await self.store.add(key, self.rules.window_s)
        except RedisError:
            log.warning("login throttle: Redis unreachable; failure not counted", exc_info=True)

    async def succeeded(self, username: str) -> None:
        """Clear ``username``'s failed logins."""
        try:
            await self.store.clear(_key("user", username.strip()))
        except RedisError:
            log.warning("login throttle: Redis unreachable", exc_info=True)

    async def hashing(self, fn: Callable[[], T]) -> T:
        """Run ``fn`` (which hashes or verifies a password) in a hashing thread; :class:`LoginRefusedError` when
        too many logins wait already."""
        loop = asyncio.get_running_loop()
        if self._limiter is None or self._loop is not loop:
            self._limiter, self._loop = anyio.CapacityLimiter(self.concurrency), loop
        if self._in_flight >= self.concurrency + self.waiting_max:
            raise LoginRefusedError("too many logins at once; try again shortly", 1.0)
        self._in_flight += 1
        try:
            return await anyio.to_thread.run_sync(fn, limiter=self._limiter)
        finally:
            self._in_flight -= 1
