"""When a vehicle's conditions begin and end: the pure state machine behind the control room's event log.

Each processed frame says which conditions hold for its vehicle (:func:`frame_conditions`): ``lost`` while
the localiser is lost, ``obscured`` while the camera check finds the camera obscured, ``low_confidence`` once
the positions have been unmatched (confidence under the localiser's match threshold, not lost) for
``EventParams.low_confidence_s`` of the vehicle's clock without a break. Against the kinds open in the log,
:func:`transitions` says which events to open and which to close; a processed frame also ends ``stale`` (the
vehicle is back). Silence is judged on the server's clock (:func:`silent`): a vehicle whose last position
arrived more than ``stale_after_s`` ago is stale since that moment plus ``stale_after_s``
(:func:`stale_since`).

The memory carried from frame to frame is one number (:class:`Watch`), stored with the vehicle's live state,
and the open kinds are read from the log itself, so any server process can judge a vehicle's next frame.
Nothing here touches storage: :mod:`driftmap.live.event_watch` reads and writes the log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timedelta

from driftmap.config import Settings
from driftmap.errors import BadInputError
from driftmap.store.event_models import EventKind

FRAME_KINDS: frozenset[EventKind] = frozenset({"lost", "obscured", "low_confidence", "stale"})
"""The kinds a processed frame judges (opens or ends); ``start_known`` is a user's action."""


@dataclass(frozen=True)
class EventParams:
    """How conditions become events."""

    low_confidence_s: float = 10.0
    # unmatched positions for this long of the vehicle's clock open ``low_confidence``, seconds

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low_confidence_s) and self.low_confidence_s >= 0):
            raise BadInputError(
                f"must be a finite number of seconds >= 0, got {self.low_confidence_s}",
                field="low_confidence_s",
            )

    @classmethod
    def of(cls, settings: Settings) -> EventParams:
        """The parameters of the server's settings (``DRIFTMAP_EVENT_LOW_CONFIDENCE_S``)."""
        return cls(low_confidence_s=settings.event_low_confidence_s)


DEFAULT_EVENTS = EventParams()


@dataclass(frozen=True)
class FrameFacts:
    """What one processed frame says about its vehicle."""

    t_s: float
    """The frame's time on the vehicle's clock, seconds."""
    lost: bool
    """The localiser is lost."""
    matched: bool
    """The position's confidence reached the localiser's match threshold (and it is not lost)."""
    obscured: bool
    """The camera check finds the camera obscured."""


@dataclass(frozen=True)
class Watch:
    """The memory carried from one frame of a vehicle to its next."""

    low_since_s: float | None = None
    """``t`` of the first frame of the current run of unmatched, not lost frames, seconds; None: no run."""


@dataclass(frozen=True)
class Transitions:
    """Events to open and to close, each in a fixed order (by kind name)."""

    opened: tuple[EventKind, ...]
    closed: tuple[EventKind, ...]


def frame_conditions(
    watch: Watch, facts: FrameFacts, params: EventParams = DEFAULT_EVENTS
) -> tuple[frozenset[EventKind], Watch]:
    """The conditions a frame shows and the memory for the vehicle's next frame.

    A lost frame breaks an unmatched run (``lost`` says more); a run's start later than the frame (a clock
    that went back) starts the run again at the frame.
    """
    active: set[EventKind] = set()
    if facts.lost:
        active.add("lost")
    if facts.obscured:
        active.add("obscured")
    low_since = None
    if not facts.matched and not facts.lost:
        start = watch.low_since_s
        low_since = facts.t_s if start is None or start > facts.t_s else start
        if facts.t_s - low_since >= params.low_confidence_s:
            active.add("low_confidence")
    return frozenset(active), Watch(low_since)


def transitions(
    open_kinds: frozenset[str], active: frozenset[EventKind], judged: frozenset[EventKind] = FRAME_KINDS
) -> Transitions:
    """Open the ``active`` conditions that are not open; close the open ``judged`` kinds that are not active."""
    opened = sorted(active - open_kinds)
    closed = sorted(k for k in judged if k in open_kinds and k not in active)
    return Transitions(tuple(opened), tuple(closed))


def judge_frame(
    open_kinds: frozenset[str], watch: Watch, facts: FrameFacts, params: EventParams = DEFAULT_EVENTS
) -> tuple[Transitions, Watch]:
    """:func:`frame_conditions` then :func:`transitions`: what one frame changes in the log."""
    active, watch = frame_conditions(watch, facts, params)
    return transitions(open_kinds, active), watch


def silent(reported_at: datetime, now: datetime, stale_after_s: float) -> bool:
    """Whether a vehicle whose last position arrived at ``reported_at`` is stale at ``now`` (UTC)."""
    return (now - reported_at).total_seconds() > stale_after_s


def stale_since(reported_at: datetime, stale_after_s: float) -> datetime:
    """When a vehicle silent since ``reported_at`` became stale: ``stale_after_s`` seconds later."""
    return reported_at + timedelta(seconds=stale_after_s)


def silence_cutoff(now: datetime, stale_after_s: float) -> datetime:
    """Vehicles whose last position arrived before this are stale at ``now``."""
    return now - timedelta(seconds=stale_after_s)
