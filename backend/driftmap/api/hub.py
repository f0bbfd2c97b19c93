"""Push of live position updates to WebSocket watchers, behind a small interface.

:class:`InMemoryHub` serves the watchers of one server process. A hub over Redis pub/sub (for several API
processes) implements the same two methods; nothing else in the API changes. A watcher that falls more than
``queue_size`` messages behind is marked ``overflowed`` and catches up from the position history, so a slow
client never slows the frame endpoint down.
"""

from __future__ import annotations

import asyncio
from typing import Any, Protocol

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

    async def publish(self, message: Message) -> None:
        for subscription in list(self._subscriptions):
            subscription.offer(message)

    def subscribe(self) -> Subscription:
        subscription = Subscription(self.queue_size)
        self._subscriptions.add(subscription)
        return subscription

    def unsubscribe(self, subscription: Subscription) -> None:
        self._subscriptions.discard(subscription)

    @property
    def watchers(self) -> int:
        """Number of current subscriptions."""
        return len(self._subscriptions)
