"""A vehicle's known start, given live: seed its stored localiser belief as ``driftmap localise --start`` does.

:func:`seed_known_start` builds the vehicle's localiser on its site's latest map version with the start
([SSLAM]'s X_0: the nearest node and the nodes within ``radius_m`` of it) and the vehicle's camera, and
stores that localiser's state as the vehicle's live state. The stored revision moves on, so every server
process rebuilds its cached localiser from the stored state at the vehicle's next frame; the frame counts and
the last frame time stay (a frame must still be newer than the last one processed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session
from sqlalchemy.orm.exc import StaleDataError

from driftmap.core.localisation.camera_check import ObscuredState
from driftmap.core.localisation.map import LocaliserMap
from driftmap.errors import BadInputError, ConflictError
from driftmap.live.localise import LiveMaps, encode_state, live_state_row, require_map_version
from driftmap.services.localisation import load_version_localiser_map, make_localiser
from driftmap.services.vehicles import get_vehicle, vehicle_camera
from driftmap.store.blobs import BlobStore
from driftmap.store.models import utc_now

MAX_START_RADIUS_M = 200.0  # a start less sure than this is no start: leave the belief global


@dataclass(frozen=True)
class SeededStart:
    """A known start stored as a vehicle's live belief."""

    vehicle_id: int
    x: float
    y: float
    radius_m: float
    node: int
    """The map node nearest to the start."""
    map_version: int
    """The version number of the site's map the belief lives on."""


def _check_start(x: float, y: float, radius_m: float) -> None:
    for name, value in (("x", x), ("y", y), ("radius_m", radius_m)):
        if not math.isfinite(value):
            raise BadInputError(f"must be a finite number, got {value}", field=name)
    if not 0.0 <= radius_m <= MAX_START_RADIUS_M:
        raise BadInputError(
            f"must be between 0 and {MAX_START_RADIUS_M:g} m, got {radius_m}", field="radius_m"
        )


def _off_map_field(lmap: LocaliserMap, x: float, y: float) -> str:
    """``x`` or ``y``: the coordinate that lies further from the map's nearest node."""
    dx, dy = np.abs(lmap.centres_m[lmap.nearest_node(x, y)] - np.array([x, y]))
    return "x" if dx >= dy else "y"


def seed_known_start(
    session: Session,
    blobs: BlobStore,
    vehicle_id: int,
    x: float,
    y: float,
    radius_m: float,
    maps: LiveMaps | None = None,
) -> SeededStart:
    """Store a known start (survey frame, metres) as the vehicle's live localiser belief.

    Args:
        session: the request's session (the caller commits).
        blobs: the blob store (map blobs).
        vehicle_id: the vehicle.
        x: the start's x (east), survey frame, metres.
        y: the start's y (north), survey frame, metres.
        radius_m: the belief covers the nodes within this of the start's nearest node, metres (0-200).
        maps: a map cache to load the site's map through (loaded afresh when None).

    Raises:
        NotFoundError: no such vehicle.
        BadInputError: a non-finite coordinate, a radius out of range, or a start more than 50 m from every
            node of the map (field ``x``, ``y`` or ``radius_m``); nothing is stored.
        ConflictError: the site has no map yet, or the vehicle's state changed meanwhile (send it again).
    """
    _check_start(x, y, radius_m)
    vehicle = get_vehicle(session, vehicle_id)
    version = require_map_version(session, vehicle.site_id)
    lmap = (
        maps.get(session, blobs, version)
        if maps is not None
        else load_version_localiser_map(session, blobs, version)
    )
    try:
        localiser = make_localiser(
            lmap, start_xy_m=(x, y), start_radius_m=radius_m, camera=vehicle_camera(vehicle)
        )
    except BadInputError as exc:
        if exc.field != "start":
            raise
        raise BadInputError(exc.reason, field=_off_map_field(lmap, x, y)) from None
    node = lmap.nearest_node(x, y)
    state = live_state_row(session, vehicle.id)
    state.state_npz = encode_state(localiser.state(), ObscuredState())
    state.map_version_id = version.id
    state.updated_at = utc_now()  # an update even when nothing else differs: the revision moves on
    try:
        session.flush()
    except (StaleDataError, IntegrityError) as exc:
        raise ConflictError(
            f"vehicle {vehicle.name!r}'s live state changed while the start was stored; send the start again"
        ) from exc
    return SeededStart(vehicle.id, x, y, radius_m, int(node), version.version)
