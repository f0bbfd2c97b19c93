"""Localiser worker processes of the live server, shared fairly by the vehicles.

The localiser step (SAD over the candidate nodes) and the database write are CPU-bound Python and numpy; in
threads they would hold the GIL against the event loop that answers every other request. So each server
process runs ``processes`` single-process pools. A vehicle's frame goes to a free process, the one that ran the
vehicle last when it is free (it keeps the vehicle's :class:`~driftmap.live.localise.LiveSlot`, the localiser
with its cached transition matrices, and the map cache of its site); when every process is busy, vehicles
wait in one queue and each freed process goes to the vehicle that has waited longest. Pinning a vehicle to
``vehicle_id % processes`` instead starves the vehicles that share a crowded process (5 vehicles on 2
processes: 42 % of frames processed against 64 %). The vehicle's state row in the database stays the truth:
a process that meets a newer revision than its slot's reloads the state from it.
"""

from __future__ import annotations

import asyncio
import functools
import multiprocessing
from collections import deque
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import TypeVar

from sqlalchemy.exc import SQLAlchemyError

from driftmap.config import Settings
from driftmap.errors import ConflictError
from driftmap.formats.frame_images import decode_gray
from driftmap.live import localise
from driftmap.live.events import DEFAULT_EVENTS, EventParams
from driftmap.live.localise import FrameOutcome, LiveMaps, LiveSlot
from driftmap.processes import end_with_parent
from driftmap.store.storage import Storage

R = TypeVar("R")

# State of one worker process (set by _start_worker).
_storage: Storage | None = None
_maps = LiveMaps()
_slots: dict[int, LiveSlot] = {}
_events: EventParams = DEFAULT_EVENTS


def _start_worker(settings_json: str) -> None:
    global _storage, _events
    settings = Settings.model_validate_json(settings_json)
    _storage = Storage.open(settings, upgrade=False)
    _events = EventParams.of(settings)
    end_with_parent()  # a killed server leaves no localiser process holding the map and the database


def _opened() -> Storage:
    assert _storage is not None, "worker process not started"
    return _storage


def _ping() -> bool:
    return _storage is not None


class LiveDatabaseError(RuntimeError):
    """A database error in a localiser process, as plain text: SQLAlchemy's errors carry the statement's
    parameters (frame bytes as ``memoryview`` on PostgreSQL), which cannot be pickled back to the server."""


def _database_errors_as_text(fn: Callable[..., R]) -> Callable[..., R]:
    @functools.wraps(fn)
    def run(*args: object) -> R:
        try:
            return fn(*args)
        except SQLAlchemyError as exc:
            raise LiveDatabaseError(f"{type(exc).__name__}: {getattr(exc, 'orig', None) or exc}") from None

    return run


@_database_errors_as_text
def _localise(vehicle_id: int, t_s: float, data: bytes, counts: tuple[int, int]) -> FrameOutcome:
    storage = _opened()
    frame = decode_gray(data, "frame")
    slot = _slots.pop(vehicle_id, None)
    outcome, slot = localise.localise_live_frame(
        storage.db, storage.blobs, _maps, vehicle_id, t_s, frame, counts, slot, _events
    )
    if slot is not None:
        _slots[vehicle_id] = slot
    return outcome


@_database_errors_as_text
def _store_counts(vehicle_id: int, skipped: int, out_of_order: int) -> None:
    before, after = localise.add_counts(_opened().db, vehicle_id, skipped, out_of_order)
    slot = _slots.get(vehicle_id)
    if slot is not None and slot.revision == before:
        slot.revision = after  # only the counts changed: the localiser stays valid


class LocaliserWorkers:
    """``processes`` localiser processes, started on first use (or by :meth:`start`).

    Args:
        settings: the server settings (the workers open the same database and blob store).
        processes: number of worker processes (about one per core).
    """

    def __init__(self, settings: Settings, processes: int = 2) -> None:
        self._settings_json = settings.model_dump_json()
        self._pools: list[ProcessPoolExecutor | None] = [None] * max(1, processes)
        self._busy = [False] * len(self._pools)
        self._last: dict[int, int] = {}
        """Index of the process that ran each vehicle last (it holds the vehicle's slot)."""
        self._waiting: deque[asyncio.Future[int]] = deque()
        """Vehicles waiting for a process, longest-waiting first."""

    def _pool(self, index: int) -> ProcessPoolExecutor:
        pool = self._pools[index]
        if pool is None:
            pool = ProcessPoolExecutor(
                max_workers=1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_worker,
                initargs=(self._settings_json,),
            )
            self._pools[index] = pool
        return pool

    async def start(self) -> None:
        """Start every worker process now (instead of at the first frame)."""
        loop = asyncio.get_running_loop()
        await asyncio.gather(*(loop.run_in_executor(self._pool(i), _ping) for i in range(len(self._pools))))

    async def localise(
        self, vehicle_id: int, t_s: float, data: bytes, counts: tuple[int, int]
    ) -> FrameOutcome:
        """Decode and localise one frame of ``vehicle_id`` in a worker process; see ``localise_live_frame``."""
        return await self._run(vehicle_id, _localise, vehicle_id, t_s, data, counts)

    async def store_counts(self, vehicle_id: int, skipped: int, out_of_order: int) -> None:
        """Add skipped and out-of-order frames to the vehicle's stored counts, in a worker process."""
        await self._run(vehicle_id, _store_counts, vehicle_id, skipped, out_of_order)

    async def _acquire(self, vehicle_id: int) -> int:
        """A free process for ``vehicle_id`` (its last one if free), after the vehicles waiting before it."""
        free = [i for i, busy in enumerate(self._busy) if not busy]
        if free and not self._waiting:
            last = self._last.get(vehicle_id)
            index = last if last in free else free[0]
            self._busy[index] = True
            return index
        turn: asyncio.Future[int] = asyncio.get_running_loop().create_future()
        self._waiting.append(turn)
        try:
            return await turn
        except asyncio.CancelledError:
            if turn.done() and not turn.cancelled():
                self._release(turn.result())  # handed a process just as the caller gave up
            else:
                self._waiting.remove(turn)
            raise

    def _release(self, index: int) -> None:
        """Hand process ``index`` to the longest-waiting vehicle, or mark it free."""
        while self._waiting:
            turn = self._waiting.popleft()
            if not turn.done():
                turn.set_result(index)
                return
        self._busy[index] = False

    async def _run(self, vehicle_id: int, fn: Callable[..., R], *args: object) -> R:
        index = await self._acquire(vehicle_id)
        try:
            self._last[vehicle_id] = index
            return await asyncio.get_running_loop().run_in_executor(self._pool(index), fn, *args)
        except BrokenProcessPool as exc:
            self._pools[index] = None  # started again on the next frame
            raise ConflictError(
                f"the localiser process of vehicle {vehicle_id} died; send the frame again"
            ) from exc
        finally:
            self._release(index)

    def close(self) -> None:
        """Stop the worker processes (after the frames they are localising)."""
        for pool in self._pools:
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
        self._pools = [None] * len(self._pools)
