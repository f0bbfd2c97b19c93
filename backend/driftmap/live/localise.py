"""Live localisation of vehicles: one frame in, one estimate out, the HMM state kept in the database.

:func:`localise_live_frame` is the synchronous step the server runs in a worker thread, one frame of one
vehicle at a time (the caller serialises a vehicle's frames). It localises on the latest map version of the
vehicle's site, stores the estimate as a :class:`~driftmap.store.access_models.VehiclePosition` and the
localiser's belief in the vehicle's :class:`~driftmap.store.access_models.VehicleLiveState`, whose version
counter makes two processes that advance the same vehicle fail instead of double-processing a frame.
A frame whose ``t`` is not after the last processed one is refused and counted, never processed.
Each processed frame is also judged for an obscured camera (:mod:`driftmap.core.localisation.camera_check`); that judgement's
memory of the recent frames is kept in the same stored state (``obscured_*`` arrays of the ``.npz``). The
frame's conditions then open and end the vehicle's events (:mod:`driftmap.live.events`) in the same
transaction, without ever failing the frame (:func:`driftmap.live.event_watch.record_frame_events`).

A vehicle with a calibrated camera (:func:`driftmap.services.vehicles.vehicle_camera`) is localised with its
ground-plane odometry; without one by appearance alone, and every estimate says ``odometry=False``. Reported
numbers that the localiser does not know (NaN heading or speed) are stored and answered as None.
"""

from __future__ import annotations

import io
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from datetime import datetime
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session
from sqlalchemy.orm.exc import StaleDataError

from driftmap.core.localisation.camera_check import ObscuredState, frame_measures, judge_obscured
from driftmap.core.localisation.localiser import Estimate, Localiser, LocaliserState
from driftmap.core.localisation.map import LocaliserMap
from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.live.event_watch import record_frame_events
from driftmap.live.events import DEFAULT_EVENTS, EventParams, FrameFacts, Watch, frame_conditions
from driftmap.services.events import EventChange
from driftmap.services.localisation import load_version_localiser_map, make_localiser
from driftmap.services.vehicles import check_frame_size, vehicle_camera
from driftmap.store.access_models import Vehicle, VehicleLiveState, VehiclePosition
from driftmap.store.blobs import BlobStore
from driftmap.store.db import Database
from driftmap.store.models import MapVersion, Site, utc_now
from driftmap.store.queries import latest_map_version

FrameStatus = Literal["processed", "skipped", "out_of_order"]
STALE_RETRIES = 3  # attempts when another process changed the vehicle's state between read and write
OBSCURED_PREFIX = "obscured_"  # arrays of the obscured-camera judgement in the stored state


class LiveMaps:
    """Localiser maps by map version id, loaded once per process (the ``capacity`` most recent kept)."""

    def __init__(self, capacity: int = 4) -> None:
        self.capacity = capacity
        self._maps: OrderedDict[int, LocaliserMap] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, session: Session, blobs: BlobStore, version: MapVersion) -> LocaliserMap:
        """The :class:`LocaliserMap` of ``version``, from the cache or loaded now."""
        with self._lock:
            found = self._maps.get(version.id)
            if found is None:
                found = load_version_localiser_map(session, blobs, version)
                self._maps[version.id] = found
                while len(self._maps) > self.capacity:
                    self._maps.popitem(last=False)
            self._maps.move_to_end(version.id)
            return found


@dataclass
class LiveSlot:
    """A vehicle's localiser kept between frames in one process; valid while the stored revision matches."""

    map_version_id: int
    localiser: Localiser
    revision: int
    obscured: ObscuredState = field(default_factory=ObscuredState)
    has_camera: bool = False
    """The localiser was built with the vehicle's camera (its estimates may carry odometry)."""


@dataclass(frozen=True)
class FrameOutcome:
    """What became of one posted frame; counts are the vehicle's totals after it."""

    vehicle_id: int
    vehicle: str
    site_id: int
    t: float
    status: FrameStatus
    processed: int
    skipped: int
    out_of_order: int
    seq: int | None = None
    """The stored position's id (the live stream's sequence number) when processed."""
    node: int | None = None
    x: float | None = None
    """Survey-frame metres (east) of the continuous position estimate."""
    y: float | None = None
    """Survey-frame metres (north) of the continuous position estimate."""
    yaw: float | None = None
    """Heading, radians counter-clockwise from +x (east); None when unknown."""
    speed_mps: float | None = None
    """Speed from the camera odometry, metres per second (negative: reversing); None when not measured."""
    moving: bool | None = None
    odometry: bool = False
    """This frame's motion came from the vehicle camera's odometry."""
    confidence: float | None = None
    """The calibrated probability, 0-1, that the position is right."""
    matched: bool | None = None
    lost: bool | None = None
    map_version: int | None = None
    received_at: datetime | None = None
    ms: float | None = None
    """Localiser step time, milliseconds."""
    obscured: bool | None = None
    """The camera looks obscured (dust, water or a covered lens), judged over the recent frames."""
    obscured_reason: str | None = None
    """``dust``, ``water`` or ``covered`` when obscured."""
    salient: float | None = None
    """Smoothed SESAME salient fraction of the frames, 0-1."""
    sharpness: float | None = None
    """Smoothed variance of the Laplacian, grey levels squared."""
    speckle: float | None = None
    """Smoothed fraction of isolated outlier pixels (dust), 0-1."""
    flat_area: float | None = None
    """Fraction of the image persistently without detail (water drop), 0-1."""
    events: tuple[EventChange, ...] = ()
    """The events this frame opened and ended."""


def decode_state(data: bytes) -> tuple[LocaliserState, ObscuredState]:
    """A stored localiser state and obscured-camera memory (a fresh one when the state has none)."""
    with np.load(io.BytesIO(data)) as arrays:
        loaded = {k: arrays[k] for k in arrays.files}
    obscured = {
        k.removeprefix(OBSCURED_PREFIX): v for k, v in loaded.items() if k.startswith(OBSCURED_PREFIX)
    }
    localiser = {k: v for k, v in loaded.items() if not k.startswith(OBSCURED_PREFIX)}
    return (
        LocaliserState.from_arrays(localiser),
        ObscuredState.from_arrays(obscured) if obscured else ObscuredState(),
    )


def encode_state(state: LocaliserState, obscured: ObscuredState) -> bytes:
    """The ``.npz`` bytes of a localiser state and obscured-camera memory."""
    arrays = dict(state.to_arrays())
    arrays.update({OBSCURED_PREFIX + k: v for k, v in obscured.to_arrays().items()})
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def require_map_version(session: Session, site_id: int) -> MapVersion:
    """The newest map version of a site; ConflictError when the site has none yet."""
    version = latest_map_version(session, site_id)
    if version is None:
        site = session.get(Site, site_id)
        name = site.name if site is not None else str(site_id)
        raise ConflictError(f"site {name!r} has no map yet: build one before vehicles can be localised")
    return version


def finite_or_none(value: float) -> float | None:
    """``value`` as a float, None when it is NaN or infinite (JSON has no NaN)."""
    value = float(value)
    return value if math.isfinite(value) else None


@dataclass(frozen=True)
class Motion:
    """The reported motion of one estimate: what the API answers and the database stores."""

    yaw: float | None
    speed_mps: float | None
    moving: bool
    odometry: bool

    @classmethod
    def of(cls, estimate: Estimate, has_camera: bool) -> Motion:
        """The motion fields of ``estimate`` (odometry only ever with a camera)."""
        return cls(
            yaw=finite_or_none(estimate.yaw_rad),
            speed_mps=finite_or_none(estimate.speed_mps),
            moving=bool(estimate.moving),
            odometry=bool(estimate.odometry) and has_camera,
        )


def live_state_row(session: Session, vehicle_id: int) -> VehicleLiveState:
    """The vehicle's live state row, added to ``session`` (with zero counts) when it has none."""
    state = session.get(VehicleLiveState, vehicle_id)
    if state is None:
        state = VehicleLiveState(vehicle_id=vehicle_id, processed=0, skipped=0, out_of_order=0)
        session.add(state)
    return state


def _ensure_live_state(db: Database, vehicle_id: int) -> None:
    """Create the vehicle's state row when it has none, in its own transaction.

    Two server processes may take a vehicle's first frames at the same time: both would insert the row in the
    frame's transaction and the second would fail on the unique key. Created apart, the loser of that race
    just finds the row (its frame then meets the revision check like any other).
    """
    try:
        with db.session() as session:
            if session.get(VehicleLiveState, vehicle_id) is None:
                session.add(VehicleLiveState(vehicle_id=vehicle_id, processed=0, skipped=0, out_of_order=0))
    except IntegrityError:
        pass  # created by another process meanwhile (or no such vehicle: the frame's transaction says so)


def _outcome(vehicle: Vehicle, state: VehicleLiveState, t_s: float, status: FrameStatus) -> FrameOutcome:
    return FrameOutcome(
        vehicle.id,
        vehicle.name,
        vehicle.site_id,
        t_s,
        status,
        state.processed,
        state.skipped,
        state.out_of_order,
    )


def localise_live_frame(
    db: Database,
    blobs: BlobStore,
    maps: LiveMaps,
    vehicle_id: int,
    t_s: float,
    frame: NDArray[np.uint8],
    unsaved_counts: tuple[int, int],
    slot: LiveSlot | None,
    events: EventParams = DEFAULT_EVENTS,
) -> tuple[FrameOutcome, LiveSlot | None]:
    """Localise one frame of a vehicle and store the estimate and the new state (one transaction).

    Args:
        db: the database.
        blobs: the blob store (map blobs).
        maps: the process's map cache.
        vehicle_id: the vehicle.
        t_s: the frame's timestamp on the vehicle's clock, seconds.
        frame: (H, W) uint8 grey frame.
        unsaved_counts: frames of this vehicle skipped under overload and refused as out of order since
            the last stored frame (added to its counts).
        slot: this process's localiser of the vehicle from the previous frame, or None.
        events: how the frame's conditions become events.

    Returns:
        The outcome and the slot to pass with the vehicle's next frame.
    """
    if not np.isfinite(t_s):
        raise BadInputError(f"t must be a finite number of seconds, got {t_s}", field="t")
    if slot is None:  # (with a slot, this process stored the vehicle's state before)
        _ensure_live_state(db, vehicle_id)
    for _attempt in range(STALE_RETRIES):
        try:
            return _localise_once(db, blobs, maps, vehicle_id, t_s, frame, unsaved_counts, slot, events)
        except StaleDataError:
            slot = None  # another process advanced the vehicle: start again from the stored state
    raise ConflictError(
        f"vehicle {vehicle_id}'s state keeps being advanced by other server processes; frame t={t_s} not processed"
    )


def _localise_once(
    db: Database,
    blobs: BlobStore,
    maps: LiveMaps,
    vehicle_id: int,
    t_s: float,
    frame: NDArray[np.uint8],
    unsaved_counts: tuple[int, int],
    slot: LiveSlot | None,
    events: EventParams,
) -> tuple[FrameOutcome, LiveSlot | None]:
    with db.session() as session:
        vehicle = session.get(Vehicle, vehicle_id)
        if vehicle is None:
            raise NotFoundError(f"no vehicle with id {vehicle_id}")
        check_frame_size(vehicle, frame)
        version = require_map_version(session, vehicle.site_id)
        state = live_state_row(session, vehicle_id)
        state.skipped += unsaved_counts[0]
        state.out_of_order += unsaved_counts[1]
        stored_revision = state.revision
        if state.last_t_s is not None and t_s <= state.last_t_s:
            state.out_of_order += 1
            session.flush()
            if slot is not None and slot.revision == stored_revision:
                slot.revision = state.revision  # the belief did not change, the slot stays valid
            return _outcome(vehicle, state, t_s, "out_of_order"), slot
        if slot is None or slot.map_version_id != version.id or slot.revision != stored_revision:
            calibrated = vehicle_camera(vehicle)
            localiser = make_localiser(maps.get(session, blobs, version), camera=calibrated)
            obscured_memory = ObscuredState()
            if state.state_npz is not None:
                stored, obscured_memory = decode_state(state.state_npz)
                if state.map_version_id == version.id:
                    localiser.restore(stored)
            slot = LiveSlot(version.id, localiser, -1, obscured_memory, has_camera=calibrated is not None)
        # the localiser's SESAME query mask also gives the camera check its salient fraction
        mask = slot.localiser.query_mask(frame)
        measures = frame_measures(frame, salient=None if mask is None else float(mask.mean()))
        estimate = slot.localiser.step(frame, t_s, mask=mask)
        motion = Motion.of(estimate, slot.has_camera)
        slot.obscured, camera = judge_obscured(slot.obscured, measures, t_s)
        received_at = utc_now()
        facts = FrameFacts(t_s, bool(estimate.lost), bool(estimate.matched), bool(camera.obscured))
        active, watch = frame_conditions(Watch(state.low_confidence_since_s), facts, events)
        state.low_confidence_since_s, state.reported_at = watch.low_since_s, received_at
        state.map_version_id = version.id
        state.last_t_s = t_s
        state.state_npz = encode_state(slot.localiser.state(), slot.obscured)
        state.processed += 1
        position = VehiclePosition(
            vehicle_id=vehicle_id,
            map_version_id=version.id,
            t_s=t_s,
            node=estimate.node,
            x_m=estimate.x_m,
            y_m=estimate.y_m,
            yaw_rad=motion.yaw,
            speed_mps=motion.speed_mps,
            moving=motion.moving,
            odometry=motion.odometry,
            confidence=estimate.confidence,
            matched=estimate.matched,
            lost=estimate.lost,
            received_at=received_at,
            obscured=camera.obscured,
            obscured_reason=camera.reason,
            salient=camera.salient,
            sharpness=camera.sharpness,
            speckle=camera.speckle,
            flat_area=camera.flat_area,
        )
        session.add(position)
        session.flush()
        slot.revision = state.revision
        changes = record_frame_events(
            session, vehicle, active, received_at, estimate.x_m, estimate.y_m, {"obscured": camera.reason}
        )
        outcome = FrameOutcome(
            vehicle.id,
            vehicle.name,
            vehicle.site_id,
            t_s,
            "processed",
            state.processed,
            state.skipped,
            state.out_of_order,
            seq=position.id,
            node=estimate.node,
            x=estimate.x_m,
            y=estimate.y_m,
            yaw=motion.yaw,
            speed_mps=motion.speed_mps,
            moving=motion.moving,
            odometry=motion.odometry,
            confidence=estimate.confidence,
            matched=estimate.matched,
            lost=estimate.lost,
            map_version=version.version,
            received_at=received_at,
            ms=estimate.ms,
            obscured=camera.obscured,
            obscured_reason=camera.reason,
            salient=camera.salient,
            sharpness=camera.sharpness,
            speckle=camera.speckle,
            flat_area=camera.flat_area,
            events=changes,
        )
    return outcome, slot


def add_counts(db: Database, vehicle_id: int, skipped: int, out_of_order: int) -> tuple[int | None, int]:
    """Add frames skipped and refused to a vehicle's stored counts; returns its revision before and after."""
    _ensure_live_state(db, vehicle_id)
    with db.session() as session:
        state = live_state_row(session, vehicle_id)
        before = state.revision
        state.skipped += skipped
        state.out_of_order += out_of_order
        session.flush()
        return before, state.revision
