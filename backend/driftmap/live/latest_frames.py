"""The newest localised frame of each vehicle, as it was posted (``GET /api/vehicles/{id}/frames/latest``).

:class:`MemoryFrames` keeps them in the server process (one API process); :class:`RedisFrames` in Redis
(bytes and ``t`` per vehicle, with an expiry) so any API process serves the frame another one localised.
Both keep the frame with the largest ``t``: a slower process never replaces a newer frame with an older one.
"""

from __future__ import annotations

from typing import Protocol

import redis.asyncio as aioredis

LATEST_FRAME_TTL_S = 3600
"""How long Redis keeps a vehicle's latest frame after it was stored, seconds."""

# KEYS[1] the vehicle's hash; ARGV: t, bytes, expiry seconds. Replaces the stored frame only by a newer one.
_PUT_NEWER = """
local old = redis.call('HGET', KEYS[1], 't')
if old and tonumber(old) >= tonumber(ARGV[1]) then return 0 end
redis.call('HSET', KEYS[1], 't', ARGV[1], 'data', ARGV[2])
redis.call('EXPIRE', KEYS[1], ARGV[3])
return 1
"""


class LatestFrames(Protocol):
    """Where the newest localised frame of each vehicle is kept."""

    async def start(self) -> None:
        """Connect (inside the server's event loop)."""
        ...

    async def close(self) -> None:
        """Disconnect."""
        ...

    async def put(self, vehicle_id: int, t: float, data: bytes) -> None:
        """Keep ``data`` (PNG/JPEG bytes) as the vehicle's frame unless one with a larger ``t`` is kept."""
        ...

    async def get(self, vehicle_id: int) -> tuple[float, bytes] | None:
        """``(t, bytes)`` of the vehicle's newest kept frame, or None."""
        ...


class MemoryFrames:
    """The frames localised by this process, in its memory (no expiry)."""

    def __init__(self) -> None:
        self._frames: dict[int, tuple[float, bytes]] = {}

    async def start(self) -> None:
        return None

    async def close(self) -> None:
        return None

    async def put(self, vehicle_id: int, t: float, data: bytes) -> None:
        kept = self._frames.get(vehicle_id)
        if kept is None or t > kept[0]:
            self._frames[vehicle_id] = (t, data)

    async def get(self, vehicle_id: int) -> tuple[float, bytes] | None:
        return self._frames.get(vehicle_id)


class RedisFrames:
    """The frames of every API process on one Redis: a hash ``{prefix}{vehicle_id}`` of ``t`` and ``data``.

    Args:
        url: the Redis URL.
        ttl_s: a stored frame expires this long after it was stored, seconds.
        prefix: key prefix.
    """

    def __init__(self, url: str, ttl_s: int = LATEST_FRAME_TTL_S, prefix: str = "driftmap:frame:") -> None:
        self.url = url
        self.ttl_s = ttl_s
        self.prefix = prefix
        self._client: aioredis.Redis | None = None

    def _redis(self) -> aioredis.Redis:
        assert self._client is not None, "RedisFrames.start() was not awaited"
        return self._client

    async def start(self) -> None:
        self._client = aioredis.Redis.from_url(self.url)

    async def close(self) -> None:
        if self._client is not None:
            await self._client.aclose()
            self._client = None

    async def put(self, vehicle_id: int, t: float, data: bytes) -> None:
        await self._redis().eval(_PUT_NEWER, 1, f"{self.prefix}{vehicle_id}", repr(t), data, str(self.ttl_s))

    async def get(self, vehicle_id: int) -> tuple[float, bytes] | None:
        t, data = await self._redis().hmget(f"{self.prefix}{vehicle_id}", ["t", "data"])
        if t is None or data is None:
            return None
        return float(t), data if isinstance(data, bytes) else data.encode()
