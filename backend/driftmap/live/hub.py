"""Push of live position updates to WebSocket watchers, behind a small interface.

:class:`InMemoryHub` serves the watchers of one server process. A hub over Redis pub/sub (for several API
processes) implements the same two methods; nothing else in the API changes. A watcher that falls more than
``queue_size`` messages behind is marked ``overflowed`` and catches up from the position history, so a slow
client never slows the frame endpoint down.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from typing import Any, Protocol

import redis.asyncio as aioredis
from redis.exceptions import RedisError

log = logging.getLogger(__name__)

Message = dict[str, Any]


class Subscription:
    """One watcher's queue of messages."""

    def __init__(self, queue_size: int) -> None:
        self.queue: asyncio.Queue[Message] = asyncio.Queue(queue_size)
        self.overflowed = False

    def offer(self, message: Message) -> None:
        """Queue ``message``, or mark the watcher as overflowed when its queue is full."""
        try:
            self.queue.put_nowait(message)
        except asyncio.QueueFull:
            self.overflowed = True

    def drain(self) -> None:
        """Drop everything queued and clear the overflow mark (the caller resyncs from the database)."""
        while not self.queue.empty():
            self.queue.get_nowait()
        self.overflowed = False


class LiveHub(Protocol):
    """Where estimates are published and watchers subscribe."""

    queue_size: int

    async def start(self) -> None:
        """Connect (inside the server's event loop, before the first watcher)."""
        ...

    async def close(self) -> None:
        """Disconnect; watchers get nothing more."""
        ...

    async def publish(self, message: Message) -> None:
        """Send ``message`` to every current watcher."""
        ...

    def subscribe(self) -> Subscription:
        """A new watcher's subscription."""
        ...

    def unsubscribe(self, subscription: Subscription) -> None:
        """Stop delivering to ``subscription``."""
        ...


class InMemoryHub:
    """The hub of one process: every subscription gets every published message."""

    def __init__(self, queue_size: int = 1024) -> None:
        self.queue_size = queue_size
        self._subscriptions: set[Subscription] = set()

    async def start(self) -> None:
        return None

    async def close(self) -> None:
        return None

    async def publish(self, message: Message) -> None:
        for subscription in list(self._subscriptions):
            subscription.offer(message)

    def subscribe(self) -> Subscription:
        subscription = Subscription(self.queue_size)
        self._subscriptions.add(subscription)
        return subscription

    def unsubscribe(self, subscription: Subscription) -> None:
        self._subscriptions.discard(subscription)

    def overflow_all(self) -> None:
        """Mark every watcher overflowed: each resyncs from the database (messages were lost on the way)."""
        for subscription in list(self._subscriptions):
            subscription.overflowed = True

    @property
    def watchers(self) -> int:
        """Number of current subscriptions."""
        return len(self._subscriptions)


# Publish a vehicle's position only when its seq is newer than the last one published for that vehicle, so
# the channel never carries one vehicle's positions backwards even when two API processes race to publish.
# KEYS[1] the vehicle's last-published key; ARGV: seq, channel, message, expiry seconds.
_PUBLISH_IN_ORDER = """
local last = tonumber(redis.call('GET', KEYS[1]))
if last and tonumber(ARGV[1]) <= last then return 0 end
redis.call('SET', KEYS[1], ARGV[1], 'EX', ARGV[4])
redis.call('PUBLISH', ARGV[2], ARGV[3])
return 1
"""


class RedisHub:
    """Watchers of every API process on one Redis: messages go through a pub/sub channel.

    Each process keeps one Redis subscription (a listener task) and fans its messages out to its local
    watchers as :class:`InMemoryHub` does, with the same overflow mark. A position (a message with
    ``vehicle_id`` and ``seq``) is published only when it is newer than the last one published for its
    vehicle (an atomic check in Redis), so per-vehicle order holds across processes; an overtaken position is
    left to the history (``/api/vehicles/{id}/positions``), as a watcher would skip it anyway. When the
    listener loses Redis it reconnects and marks every watcher overflowed, so each resyncs from the database.

    Args:
        url: the Redis URL (``redis://host:port/db``).
        queue_size: messages a watcher may fall behind before it resyncs.
        channel: the pub/sub channel (also the prefix of the per-vehicle order keys).
        order_ttl_s: lifetime of a vehicle's last-published seq in Redis, seconds.
    """

    def __init__(
        self,
        url: str,
        queue_size: int = 1024,
        *,
        channel: str = "driftmap:live",
        order_ttl_s: int = 24 * 3600,
    ) -> None:
        self.url = url
        self.queue_size = queue_size
        self.channel = channel
        self.order_ttl_s = order_ttl_s
        self.skipped = 0
        """Positions not published because a newer one of the same vehicle was already out."""
        self._local = InMemoryHub(queue_size)
        self._client: aioredis.Redis | None = None
        self._listener: asyncio.Task[None] | None = None
        self._ready = asyncio.Event()

    async def start(self) -> None:
        self._client = aioredis.Redis.from_url(self.url)
        self._ready = asyncio.Event()
        self._listener = asyncio.create_task(self._listen())
        await asyncio.wait_for(self._ready.wait(), 30.0)

    async def close(self) -> None:
        if self._listener is not None:
            self._listener.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._listener
            self._listener = None
        if self._client is not None:
            await self._client.aclose()
            self._client = None

    async def publish(self, message: Message) -> None:
        assert self._client is not None, "RedisHub.start() was not awaited"
        data = json.dumps(message, separators=(",", ":"))
        if "vehicle_id" in message and "seq" in message:
            key = f"{self.channel}:last:{message['vehicle_id']}"
            sent = await self._client.eval(
                _PUBLISH_IN_ORDER, 1, key, str(message["seq"]), self.channel, data, str(self.order_ttl_s)
            )
            if not sent:
                self.skipped += 1
                log.debug(
                    "position %s overtaken by a newer one of its vehicle, not published", message["seq"]
                )
        else:
            await self._client.publish(self.channel, data)

    def subscribe(self) -> Subscription:
        self._local.queue_size = self.queue_size
        return self._local.subscribe()

    def unsubscribe(self, subscription: Subscription) -> None:
        self._local.unsubscribe(subscription)

    @property
    def watchers(self) -> int:
        """Number of this process's current subscriptions."""
        return self._local.watchers

    async def _listen(self) -> None:
        """Forward the channel to the local watchers; after a reconnection (ours, or the client's own retry,
        which Redis confirms with a new ``subscribe`` message) mark every watcher overflowed, so each resyncs
        from the database for the messages that went by meanwhile."""
        assert self._client is not None
        subscribed_before = False
        while True:
            try:
                async with self._client.pubsub() as pubsub:
                    await pubsub.subscribe(self.channel)
                    async for raw in pubsub.listen():
                        kind = raw.get("type")
                        if kind == "message":
                            await self._local.publish(json.loads(raw["data"]))
                        elif kind == "subscribe":
                            if subscribed_before:
                                self._local.overflow_all()
                            subscribed_before = True
                            self._ready.set()
            except (RedisError, OSError):
                log.warning("lost the Redis live channel; reconnecting", exc_info=True)
                await asyncio.sleep(0.5)
