"""Per-vehicle lanes that feed frames to the localiser in order, off the event loop.

Each vehicle has a lane: at most one frame of it is being localised (in a thread of a small pool, so the
event loop stays responsive) and at most ``queue_depth`` wait behind it. A frame whose ``t`` is not after
the newest frame the lane accepted is refused as ``out_of_order``. When a frame arrives and the waiting
room is full, the oldest waiting frame is skipped on purpose: its caller gets ``status="skipped"`` and the
vehicle's ``skipped`` count grows (stored with the next processed frame). Frames are never reordered and
never processed twice; every posted frame gets exactly one answer.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.api.hub import InMemoryHub, LiveHub, Message
from driftmap.config import Settings
from driftmap.formats.frame_images import decode_gray
from driftmap.services import live as live_service
from driftmap.services.live import FrameOutcome, LiveMaps, LiveSlot
from driftmap.services.positions import PositionView
from driftmap.store.access_models import VehicleLiveState
from driftmap.store.storage import Storage

log = logging.getLogger(__name__)


@dataclass
class _Waiting:
    t: float
    frame: NDArray[np.uint8]
    answer: asyncio.Future[FrameOutcome]


@dataclass
class _Lane:
    vehicle_id: int
    name: str
    site_id: int
    newest_t: float | None = None
    waiting: deque[_Waiting] = field(default_factory=deque)
    running: bool = False
    unsaved_skips: int = 0
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

    async def decode(self, data: bytes) -> NDArray[np.uint8]:
        """A posted image as a grey frame, decoded in the pool; BadInputError names what is wrong."""
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._pool, decode_gray, data, "frame")

    async def submit(
        self, vehicle_id: int, name: str, site_id: int, t: float, frame: NDArray[np.uint8]
    ) -> FrameOutcome:
        """Localise ``frame`` of a vehicle in its turn; returns its outcome (processed, skipped or out of order)."""
        lane = self._lanes.get(vehicle_id)
        if lane is None:
            lane = self._lanes[vehicle_id] = _Lane(vehicle_id, name, site_id)
        if lane.newest_t is not None and t <= lane.newest_t:
            return await self._refuse(lane, t)
        lane.newest_t = t
        answer: asyncio.Future[FrameOutcome] = asyncio.get_running_loop().create_future()
        while len(lane.waiting) >= self.queue_depth:
            dropped = lane.waiting.popleft()
            lane.unsaved_skips += 1
            if not dropped.answer.done():
                dropped.answer.set_result(self._skipped(lane, dropped.t))
        lane.waiting.append(_Waiting(t, frame, answer))
        if not lane.running:
            lane.running = True
            asyncio.create_task(self._drain(lane))  # noqa: RUF006 (the lane keeps running until empty)
        return await asyncio.shield(answer)

    def _skipped(self, lane: _Lane, t: float) -> FrameOutcome:
        last = lane.last
        processed = last.processed if last else 0
        skipped = (last.skipped if last else 0) + lane.unsaved_skips
        out_of_order = last.out_of_order if last else 0
        return FrameOutcome(
            lane.vehicle_id, lane.name, lane.site_id, t, "skipped", processed, skipped, out_of_order
        )

    async def _refuse(self, lane: _Lane, t: float) -> FrameOutcome:
        loop = asyncio.get_running_loop()
        counts = await loop.run_in_executor(self._pool, self._count_out_of_order, lane.vehicle_id)
        processed, skipped, out_of_order = counts
        outcome = FrameOutcome(
            lane.vehicle_id,
            lane.name,
            lane.site_id,
            t,
            "out_of_order",
            processed,
            skipped + lane.unsaved_skips,
            out_of_order,
        )
        if lane.last is not None:
            lane.last = replace(lane.last, out_of_order=out_of_order)
        return outcome

    def _count_out_of_order(self, vehicle_id: int) -> tuple[int, int, int]:
        with self.storage.db.session() as session:
            state = session.get(VehicleLiveState, vehicle_id)
            if state is None:
                state = VehicleLiveState(vehicle_id=vehicle_id, processed=0, skipped=0, out_of_order=0)
                session.add(state)
            state.out_of_order += 1
            session.flush()
            return state.processed, state.skipped, state.out_of_order

    async def _drain(self, lane: _Lane) -> None:
        loop = asyncio.get_running_loop()
        try:
            while lane.waiting:
                item = lane.waiting.popleft()
                skips, lane.unsaved_skips = lane.unsaved_skips, 0
                try:
                    outcome, lane.slot = await loop.run_in_executor(
                        self._pool,
                        live_service.localise_live_frame,
                        self.storage.db,
                        self.storage.blobs,
                        self.maps,
                        lane.vehicle_id,
                        item.t,
                        item.frame,
                        skips,
                        lane.slot,
                    )
                except Exception as exc:
                    lane.slot = None  # the stored state is the truth again
                    lane.unsaved_skips += skips
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
