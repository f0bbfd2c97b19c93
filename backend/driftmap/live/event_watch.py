"""The event log kept by the live path: the events of a processed frame, and the watch for silent vehicles.

:func:`record_frame_events` runs in a frame's transaction (in the localiser worker process, after the
position is stored): inside a savepoint, so that a failure is logged and undone alone while the frame's
position and state are still stored and answered. The next frame judges against the log again, so a missed
change is made then. Frames of one vehicle are localised one at a time and in order (the stored state's
revision, :mod:`driftmap.live.localise`), so only one process changes a vehicle's frame-judged events at a
time.

:class:`SilenceWatch` runs in every API process: each ``every_s`` it opens a ``stale`` event for the
vehicles whose last position came more than ``stale_after_s`` ago (:func:`open_stale_events`) and publishes
the changes. Two processes that find the same vehicle at once race on the log's one-open-event-per-kind
index: one opens the event, the other finds it open and publishes nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable, Mapping
from datetime import datetime

from sqlalchemy.orm import Session

from driftmap.live.events import silence_cutoff, stale_since, transitions
from driftmap.services import events as event_service
from driftmap.services.events import EventChange
from driftmap.store.access_models import Vehicle
from driftmap.store.db import Database
from driftmap.store.event_models import EventKind
from driftmap.store.models import utc_now

log = logging.getLogger(__name__)


def record_frame_events(
    session: Session,
    vehicle: Vehicle,
    active: frozenset[EventKind],
    at: datetime,
    x: float,
    y: float,
    details: Mapping[str, str | None] | None = None,
) -> tuple[EventChange, ...]:
    """Open and end the vehicle's events after a processed frame showing the ``active`` conditions.

    Args:
        session: the frame's session (its transaction is committed by the caller).
        vehicle: the frame's vehicle.
        active: the conditions the frame shows (:func:`driftmap.live.events.frame_conditions`).
        at: when the server received the frame, UTC (the start or end of the events it changes).
        x: the frame's position, survey-frame metres east (where opened events start).
        y: ... metres north.
        details: a few words per kind for the events opened (e.g. the obscured camera's reason).

    Returns:
        The changes, ended events first; none when the log could not be written (logged).
    """
    try:
        with session.begin_nested():
            moves = transitions(event_service.open_kinds(session, vehicle.id), active)
            changes = event_service.end_events(session, vehicle, moves.closed, at)
            for kind in moves.opened:
                detail = (details or {}).get(kind)
                changes.append(event_service.open_event(session, vehicle, kind, at, x, y, detail))
        return tuple(changes)
    except Exception:
        log.warning("could not update the event log of vehicle %s", vehicle.id, exc_info=True)
        return ()


def open_stale_events(db: Database, stale_after_s: float, now: datetime | None = None) -> list[EventChange]:
    """Open a ``stale`` event for every vehicle silent for more than ``stale_after_s`` seconds at ``now``.

    Each starts when its vehicle became stale (its last position's arrival plus ``stale_after_s``) at that
    position. Returns the events opened (not those another process opened first).
    """
    now = now or utc_now()
    opened: list[EventChange] = []
    with db.session() as session:
        for silent in event_service.silent_vehicles(session, silence_cutoff(now, stale_after_s)):
            at = stale_since(silent.reported_at, stale_after_s)
            change = event_service.open_event_once(session, silent.vehicle, "stale", at, silent.x, silent.y)
            if change is not None:
                opened.append(change)
    return opened


class SilenceWatch:
    """Opens ``stale`` events in the background of an API process and publishes them.

    Args:
        db: the database.
        publish: sends one change to the watchers (failures are logged).
        stale_after_s: a vehicle silent this long is stale, seconds.
        every_s: how often to look, seconds; 0 or less: never.
    """

    def __init__(
        self,
        db: Database,
        publish: Callable[[EventChange], Awaitable[None]],
        stale_after_s: float,
        every_s: float,
    ) -> None:
        self.db = db
        self.publish = publish
        self.stale_after_s = stale_after_s
        self.every_s = every_s
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        """Start looking (inside the server's event loop)."""
        if self.every_s > 0 and self._task is None:
            self._task = asyncio.create_task(self._run())

    async def stop(self) -> None:
        """Stop looking."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    async def check(self) -> list[EventChange]:
        """Look once: open and publish the events of the vehicles gone silent; returns them."""
        opened = await asyncio.to_thread(open_stale_events, self.db, self.stale_after_s)
        for change in opened:
            await self.publish(change)
        return opened

    async def _run(self) -> None:
        while True:
            try:
                await self.check()
            except Exception:
                log.warning("could not look for silent vehicles", exc_info=True)
            await asyncio.sleep(self.every_s)
