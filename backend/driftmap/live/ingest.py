"""Per-vehicle lanes that feed frames to the localiser in order, off the event loop.

Each vehicle has a lane: at most one frame of it is being localised (in a localiser worker process,
:mod:`driftmap.live.workers`, so the event loop stays responsive) and at most ``queue_depth`` wait
behind it, ordered by ``t``. A frame whose ``t`` is not after the newest frame handed to the localiser (or
equals a waiting one) is refused as ``out_of_order``. A frame refused as bad input (a ``t`` that is not a
finite number of seconds, an image that is not a PNG/JPEG, declares more than ``max_frame_pixels`` or cannot
be localised) changes nothing: the lane's newest ``t`` goes back to that of the frame handed on before it.
When the waiting room overflows, its oldest frame is skipped on purpose: its caller gets
``status="skipped"``. Both counts are stored with the vehicle's next processed frame. Frames are never
reordered and never processed twice; every posted frame gets exactly one answer.

Several API processes may share one database (and one Redis): a vehicle's localiser state is the stored
:class:`~driftmap.store.access_models.VehicleLiveState` (see :mod:`driftmap.live.localise`), so frames of
one vehicle posted to different processes are still localised once each and in order. A processed frame is
published to the hub and kept as the vehicle's latest frame *before* its caller gets the answer, so a
vehicle that posts its next frame after the answer (to any process) cannot overtake it on the hub. The
events a frame opened or ended are published right after its position; the process also watches for vehicles
gone silent (:class:`~driftmap.live.event_watch.SilenceWatch`) and publishes their ``stale`` events.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from driftmap.config import Settings
from driftmap.formats.bounds import check_t_s
from driftmap.formats.frame_images import check_complete, check_frame_pixels
from driftmap.live.event_watch import SilenceWatch
from driftmap.live.events import EventParams
from driftmap.live.hub import InMemoryHub, LiveHub, Message
from driftmap.live.latest_frames import LatestFrames, MemoryFrames
from driftmap.live.localise import FrameOutcome, FrameStatus
from driftmap.live.metrics import count_frame
from driftmap.live.workers import LocaliserWorkers
from driftmap.services.events import EventChange
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
    in_flight: tuple[int, int] = (0, 0)
    stored_before_last: tuple[int, int] = (0, 0)
    """(skipped, out of order) stored while ``last`` is still None (no frame processed in this process)."""
    """(skipped, out of order) handed to a worker and not yet in ``last``."""
    last: FrameOutcome | None = None


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
        yaw=outcome.yaw,
        speed_mps=outcome.speed_mps,
        moving=outcome.moving,
        odometry=outcome.odometry,
        confidence=outcome.confidence or 0.0,
        matched=bool(outcome.matched),
        lost=bool(outcome.lost),
        map_version=outcome.map_version,
        received_at=outcome.received_at,
        obscured=outcome.obscured,
        obscured_reason=outcome.obscured_reason,
        salient=outcome.salient,
        sharpness=outcome.sharpness,
        speckle=outcome.speckle,
        flat_area=outcome.flat_area,
    )


class LiveService:
    """The process's live localisation: lanes, the localiser worker processes and the hub.

    Args:
        settings: server settings.
        storage: the database and blob store.
        hub: where estimates are published (an in-process hub when None).
        frames: where the latest frame of each vehicle is kept (this process's memory when None).
        position_message: the hub message of a processed frame's position (the API's
            :func:`~driftmap.api.schemas_live.position_message`).
        event_message: the hub message of an event's change (the API's
            :func:`~driftmap.api.schemas_live.event_message`).
        queue_depth: frames of one vehicle that may wait behind the one being localised.
        processes: localiser worker processes (about one per core).
    """

    def __init__(
        self,
        settings: Settings,
        storage: Storage,
        hub: LiveHub | None = None,
        frames: LatestFrames | None = None,
        *,
        position_message: Callable[[PositionView], Message],
        event_message: Callable[[EventChange], Message],
        queue_depth: int = 1,
        processes: int = 2,
    ) -> None:
        self.settings = settings
        self.position_message = position_message
        self.event_message = event_message
        self.storage = storage
        self.hub: LiveHub = hub if hub is not None else InMemoryHub()
        self.queue_depth = max(1, queue_depth)
        self.workers = LocaliserWorkers(settings, processes)
        self.frames: LatestFrames = frames if frames is not None else MemoryFrames()
        self._lanes: dict[int, _Lane] = {}
        EventParams.of(settings)  # a bad setting fails here, not in every localiser process
        self.silence = SilenceWatch(
            storage.db, self.publish_event, settings.stale_after_s, settings.event_check_every_s
        )

    async def latest_frame(self, vehicle_id: int) -> tuple[float, bytes] | None:
        """``(t, bytes)`` of the vehicle's newest localised frame (as posted), or None."""
        return await self.frames.get(vehicle_id)

    async def start(self) -> None:
        """Start the localiser worker processes, connect the hub and the frame store, watch for silence."""
        await self.workers.start()
        await self.hub.start()
        await self.frames.start()
        self.silence.start()

    async def stop(self) -> None:
        """Stop watching, disconnect the hub and the frame store, then stop the worker processes."""
        await self.silence.stop()
        await self.hub.close()
        await self.frames.close()
        self.close()

    def close(self) -> None:
        """Stop the worker processes (after the frames being localised)."""
        self.workers.close()

    async def publish_event(self, change: EventChange) -> None:
        """Send an event's change to every watcher (a failure is logged: watchers read the log on reconnect)."""
        try:
            await self.hub.publish(self.event_message(change))
        except Exception:
            log.warning("could not publish event %s (%s)", change.event.id, change.change, exc_info=True)

    async def submit(self, vehicle_id: int, name: str, site_id: int, t: float, data: bytes) -> FrameOutcome:
        """Localise a frame (PNG or JPEG bytes) of a vehicle in its turn; returns its outcome.

        ``t`` (seconds) and the bytes are checked at once, the bytes for a complete PNG/JPEG of at most
        ``max_frame_pixels`` pixels by its header (BadInputError, PayloadTooLargeError); they are decoded only
        when the frame's turn comes, so frames skipped under overload cost nothing.
        """
        t = check_t_s(t, "t")
        check_complete(data, "frame")
        check_frame_pixels(data, "frame", self.settings.max_frame_pixels, field="body")
        lane = self._lanes.get(vehicle_id)
        if lane is None:
            lane = self._lanes[vehicle_id] = _Lane(vehicle_id, name, site_id)
        if (lane.started_t is not None and t <= lane.started_t) or any(w.t == t for w in lane.waiting):
            lane.unsaved_out_of_order += 1
            self._ensure_draining(lane)  # stores the count when nothing else is running
            count_frame("out_of_order", None)
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
        outcome = await asyncio.shield(answer)
        count_frame(outcome.status, outcome.ms)
        return outcome

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
            (last.skipped if last else lane.stored_before_last[0]) + lane.unsaved_skips + lane.in_flight[0],
            (last.out_of_order if last else lane.stored_before_last[1])
            + lane.unsaved_out_of_order
            + lane.in_flight[1],
        )

    async def _store_counts(self, lane: _Lane) -> None:
        """Store the lane's unsaved skip and out-of-order counts (when no frame is left to carry them)."""
        counts = lane.in_flight = lane.unsaved_skips, lane.unsaved_out_of_order
        lane.unsaved_skips = lane.unsaved_out_of_order = 0
        try:
            await self.workers.store_counts(lane.vehicle_id, *counts)
        except Exception:
            log.warning("could not store the frame counts of vehicle %s", lane.vehicle_id, exc_info=True)
            return
        finally:
            lane.in_flight = (0, 0)
        if lane.last is not None:
            lane.last = replace(
                lane.last,
                skipped=lane.last.skipped + counts[0],
                out_of_order=lane.last.out_of_order + counts[1],
            )
        else:
            done = lane.stored_before_last
            lane.stored_before_last = (done[0] + counts[0], done[1] + counts[1])

    async def _share(self, vehicle_id: int, item: _Waiting, outcome: FrameOutcome) -> None:
        """Keep the frame as the vehicle's latest and publish its position (failures are logged: the estimate
        is stored and watchers resync from the history)."""
        try:
            await self.frames.put(vehicle_id, item.t, item.data)
        except Exception:
            log.warning("could not keep the latest frame of vehicle %s", vehicle_id, exc_info=True)
        try:
            await self.hub.publish(self.position_message(_view(outcome)))
        except Exception:
            log.warning("could not publish position %s of vehicle %s", outcome.seq, vehicle_id, exc_info=True)
        for change in outcome.events:
            await self.publish_event(change)

    async def _drain(self, lane: _Lane) -> None:
        try:
            while lane.waiting or lane.unsaved_skips or lane.unsaved_out_of_order:
                if not lane.waiting:
                    await self._store_counts(lane)
                    continue
                item = lane.waiting.popleft()
                previous_t, lane.started_t = lane.started_t, item.t
                counts = lane.in_flight = lane.unsaved_skips, lane.unsaved_out_of_order
                lane.unsaved_skips = lane.unsaved_out_of_order = 0
                try:
                    outcome = await self.workers.localise(lane.vehicle_id, item.t, item.data, counts)
                except Exception as exc:
                    if lane.started_t == item.t:  # a refused frame leaves the order as it was
                        lane.started_t = previous_t
                    lane.in_flight = (0, 0)
                    lane.unsaved_skips += counts[0]
                    lane.unsaved_out_of_order += counts[1]
                    if not item.answer.done():
                        item.answer.set_exception(exc)
                    continue
                lane.last, lane.in_flight = outcome, (0, 0)
                if outcome.status == "processed":
                    await self._share(lane.vehicle_id, item, outcome)
                if not item.answer.done():
                    item.answer.set_result(outcome)
        finally:
            lane.running = False
