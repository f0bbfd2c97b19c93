"""Per-vehicle lanes that feed frames to the localiser in order, off the event loop.

Each vehicle has a lane: at most one frame of it is being localised (in a thread of a small pool, so the
event loop stays responsive) and at most ``queue_depth`` wait behind it, ordered by ``t``. A frame whose
``t`` is not after the newest frame handed to the localiser (or equals a waiting one) is refused as
``out_of_order``. When the waiting room overflows, its oldest frame is skipped on purpose: its caller gets
``status="skipped"``. Both counts are stored with the vehicle's next processed frame. Frames are never
reordered and never processed twice; every posted frame gets exactly one answer.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

from driftmap.api.hub import InMemoryHub, LiveHub, Message
from driftmap.config import Settings
from driftmap.formats.frame_images import check_complete, decode_gray
from driftmap.services import live as live_service
from driftmap.services.live import FrameOutcome, FrameStatus, LiveMaps, LiveSlot
from driftmap.services.positions import PositionView
from driftmap.store.storage import Storage

log = logging.getLogger(__name__)


@dataclass
class _Waiting:
    t: float
    data: bytes
    answer: asyncio.Future[FrameOutcome]


@dataclass
class _Lane:
    vehicle_id: int
    name: str
    site_id: int
    started_t: float | None = None
    """``t`` of the newest frame handed to the localiser; older frames are out of order."""
    waiting: deque[_Waiting] = field(default_factory=deque)
    running: bool = False
    unsaved_skips: int = 0
    unsaved_out_of_order: int = 0
    slot: LiveSlot | None = None
    last: FrameOutcome | None = None


def position_message(view: PositionView) -> Message:
    """The ``/api/live`` message of one position."""
    return {
        "type": "position",
        "seq": view.seq,
        "vehicle_id": view.vehicle_id,
        "vehicle": view.vehicle,
        "site_id": view.site_id,
        "t": view.t,
        "node": view.node,
        "x": view.x,
        "y": view.y,
        "yaw": view.yaw,
        "confidence": view.confidence,
        "matched": view.matched,
        "lost": view.lost,
        "map_version": view.map_version,
        "received_at": view.received_at.isoformat(),
        "stale": False,
    }


def _view(outcome: FrameOutcome) -> PositionView:
    assert outcome.seq is not None and outcome.received_at is not None
    assert outcome.node is not None and outcome.x is not None and outcome.y is not None
    return PositionView(
        seq=outcome.seq,
        vehicle_id=outcome.vehicle_id,
        vehicle=outcome.vehicle,
        site_id=outcome.site_id,
        t=outcome.t,
        node=outcome.node,
        x=outcome.x,
        y=outcome.y,
        yaw=None,
        confidence=outcome.confidence or 0.0,
        matched=bool(outcome.matched),
        lost=bool(outcome.lost),
        map_version=outcome.map_version,
        received_at=outcome.received_at,
    )


class LiveService:
    """The process's live localisation: lanes, the thread pool, the map cache and the hub.

    Args:
        settings: server settings.
        storage: the database and blob store.
        hub: where estimates are published (an in-process hub when None).
        queue_depth: frames of one vehicle that may wait behind the one being localised.
        threads: localiser threads (CPU-bound numpy work; about one per core).
    """

    def __init__(
        self,
        settings: Settings,
        storage: Storage,
        hub: LiveHub | None = None,
        *,
        queue_depth: int = 1,
        threads: int = 2,
    ) -> None:
        self.settings = settings
        self.storage = storage
        self.hub: LiveHub = hub if hub is not None else InMemoryHub()
        self.queue_depth = max(1, queue_depth)
        self.maps = LiveMaps()
        self._pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="driftmap-live")
        self._lanes: dict[int, _Lane] = {}

    def close(self) -> None:
        """Stop the thread pool (waits for frames being localised)."""
        self._pool.shutdown(wait=True, cancel_futures=True)

    async def submit(self, vehicle_id: int, name: str, site_id: int, t: float, data: bytes) -> FrameOutcome:
        """Localise a frame (PNG or JPEG bytes) of a vehicle in its turn; returns its outcome.

        The bytes are checked for a complete PNG/JPEG at once (BadInputError) and decoded only when the frame's
        turn comes, so frames skipped under overload cost nothing.
        """
        check_complete(data, "frame")
        lane = self._lanes.get(vehicle_id)
        if lane is None:
            lane = self._lanes[vehicle_id] = _Lane(vehicle_id, name, site_id)
        if (lane.started_t is not None and t <= lane.started_t) or any(w.t == t for w in lane.waiting):
            lane.unsaved_out_of_order += 1
            self._ensure_draining(lane)  # stores the count when nothing else is running
            return self._answer(lane, t, "out_of_order")
        answer: asyncio.Future[FrameOutcome] = asyncio.get_running_loop().create_future()
        lane.waiting.append(_Waiting(t, data, answer))
        lane.waiting = deque(sorted(lane.waiting, key=lambda w: w.t))
        while len(lane.waiting) > self.queue_depth:
            dropped = lane.waiting.popleft()  # the oldest waiting frame (maybe this one): stale, skip it
            lane.unsaved_skips += 1
            if not dropped.answer.done():
                dropped.answer.set_result(self._answer(lane, dropped.t, "skipped"))
        self._ensure_draining(lane)
        return await asyncio.shield(answer)

    def _ensure_draining(self, lane: _Lane) -> None:
        if not lane.running:
            lane.running = True
            asyncio.create_task(self._drain(lane))  # noqa: RUF006 (the lane keeps running until empty)

    def _answer(self, lane: _Lane, t: float, status: FrameStatus) -> FrameOutcome:
        """The outcome of a frame that is not localised, with the vehicle's counts so far."""
        last = lane.last
        return FrameOutcome(
            lane.vehicle_id,
            lane.name,
            lane.site_id,
            t,
            status,
            last.processed if last else 0,
            (last.skipped if last else 0) + lane.unsaved_skips,
            (last.out_of_order if last else 0) + lane.unsaved_out_of_order,
        )

    async def _store_counts(self, lane: _Lane) -> None:
        """Store the lane's unsaved skip and out-of-order counts (when no frame is left to carry them)."""
        counts = lane.unsaved_skips, lane.unsaved_out_of_order
        lane.unsaved_skips = lane.unsaved_out_of_order = 0
        loop = asyncio.get_running_loop()
        try:
            before, after = await loop.run_in_executor(
                self._pool, live_service.add_counts, self.storage.db, lane.vehicle_id, *counts
            )
        except Exception:
            log.warning("could not store the frame counts of vehicle %s", lane.vehicle_id, exc_info=True)
            lane.slot = None
            return
        if lane.slot is not None and lane.slot.revision == before:
            lane.slot.revision = after  # only the counts changed: the localiser stays valid
        if lane.last is not None:
            lane.last = replace(
                lane.last,
                skipped=lane.last.skipped + counts[0],
                out_of_order=lane.last.out_of_order + counts[1],
            )

    def _localise(
        self, vehicle_id: int, item: _Waiting, counts: tuple[int, int], slot: LiveSlot | None
    ) -> tuple[FrameOutcome, LiveSlot | None]:
        frame = decode_gray(item.data, "frame")
        storage = self.storage
        return live_service.localise_live_frame(
            storage.db, storage.blobs, self.maps, vehicle_id, item.t, frame, counts, slot
        )

    async def _drain(self, lane: _Lane) -> None:
        loop = asyncio.get_running_loop()
        try:
            while lane.waiting or lane.unsaved_skips or lane.unsaved_out_of_order:
                if not lane.waiting:
                    await self._store_counts(lane)
                    continue
                item = lane.waiting.popleft()
                lane.started_t = item.t
                counts = lane.unsaved_skips, lane.unsaved_out_of_order
                lane.unsaved_skips = lane.unsaved_out_of_order = 0
                try:
                    outcome, lane.slot = await loop.run_in_executor(
                        self._pool, self._localise, lane.vehicle_id, item, counts, lane.slot
                    )
                except Exception as exc:
                    lane.slot = None  # the stored state is the truth again
                    lane.unsaved_skips += counts[0]
                    lane.unsaved_out_of_order += counts[1]
                    if not item.answer.done():
                        item.answer.set_exception(exc)
                    continue
                lane.last = outcome
                if not item.answer.done():
                    item.answer.set_result(outcome)
                if outcome.status == "processed":
                    await self.hub.publish(position_message(_view(outcome)))
        finally:
            lane.running = False
