"""The event state machine: which events a stream of frames opens and ends, and when silence is stale."""

from __future__ import annotations

from collections.abc import Iterable
from datetime import UTC, datetime, timedelta

import pytest

from driftmap.errors import BadInputError
from driftmap.live.events import (
    EventParams,
    FrameFacts,
    Watch,
    judge_frame,
    silence_cutoff,
    silent,
    stale_since,
    transitions,
)

FRAME_S = 0.5  # frame period of the streams below, seconds
PARAMS = EventParams(low_confidence_s=2.0)


def frame(t: float, *, lost: bool = False, matched: bool = True, obscured: bool = False) -> FrameFacts:
    return FrameFacts(t, lost, matched and not lost, obscured)


def replay(
    frames: Iterable[FrameFacts], open_kinds: frozenset[str] = frozenset()
) -> list[tuple[float, str, str]]:
    """Feed frames as the live path does, keeping the open kinds as the log would; the (t, change, kind) list."""
    watch, log = Watch(), []
    for facts in frames:
        moves, watch = judge_frame(open_kinds, watch, facts, PARAMS)
        log += [(facts.t_s, "closed", k) for k in moves.closed] + [
            (facts.t_s, "opened", k) for k in moves.opened
        ]
        open_kinds = (open_kinds - set(moves.closed)) | set(moves.opened)
    return log


class TestFrameConditions:
    def test_lost_and_obscured_open_when_they_begin_and_close_when_they_end(self) -> None:
        stream = [
            frame(0),
            frame(0.5, lost=True),
            frame(1, lost=True, obscured=True),
            frame(1.5, obscured=True),
        ]
        stream.append(frame(2))
        assert replay(stream) == [
            (0.5, "opened", "lost"),
            (1, "opened", "obscured"),
            (1.5, "closed", "lost"),
            (2, "closed", "obscured"),
        ]

    def test_low_confidence_opens_after_an_unbroken_unmatched_run(self) -> None:
        short = [frame(FRAME_S * i, matched=i % 4 == 0) for i in range(12)]  # runs of 1.5 s
        assert replay(short) == []
        long = [frame(FRAME_S * i, matched=not 2 <= i <= 9) for i in range(12)]  # unmatched from 1.0 to 4.5 s
        assert replay(long) == [(3.0, "opened", "low_confidence"), (5.0, "closed", "low_confidence")]

    def test_a_lost_frame_breaks_the_unmatched_run_and_ends_low_confidence(self) -> None:
        stream = [frame(FRAME_S * i, matched=False) for i in range(6)]  # low_confidence at 2.0 s
        stream += [frame(3.0, lost=True)] + [frame(3.5 + FRAME_S * i, matched=False) for i in range(5)]
        assert replay(stream) == [
            (2.0, "opened", "low_confidence"),
            (3.0, "closed", "low_confidence"),
            (3.0, "opened", "lost"),
            (3.5, "closed", "lost"),
            (5.5, "opened", "low_confidence"),
        ]

    def test_the_run_is_measured_on_the_vehicle_clock_across_gaps(self) -> None:
        assert replay([frame(0, matched=False), frame(30, matched=False)]) == [
            (30, "opened", "low_confidence")
        ]

    def test_a_frame_ends_stale_and_leaves_start_known_alone(self) -> None:
        assert replay([frame(0)], frozenset({"stale", "start_known"})) == [(0, "closed", "stale")]

    def test_an_open_event_is_not_opened_twice(self) -> None:
        assert replay([frame(0, lost=True), frame(1, lost=True)], frozenset({"lost"})) == []

    def test_transitions_come_in_kind_order(self) -> None:
        moves = transitions(frozenset({"stale", "lost"}), frozenset({"obscured", "low_confidence"}))
        assert moves.opened == ("low_confidence", "obscured") and moves.closed == ("lost", "stale")

    def test_the_duration_must_be_finite_and_not_negative(self) -> None:
        for bad in (-1.0, float("nan"), float("inf")):
            with pytest.raises(BadInputError) as error:
                EventParams(low_confidence_s=bad)
            assert error.value.field == "low_confidence_s"


class TestSilence:
    def test_a_vehicle_is_stale_once_silent_longer_than_the_threshold(self) -> None:
        heard = datetime(2026, 12, 6, 8, 0, 0, tzinfo=UTC)
        assert not silent(heard, heard + timedelta(seconds=10), 10.0)
        assert silent(heard, heard + timedelta(seconds=10.001), 10.0)
        assert stale_since(heard, 10.0) == heard + timedelta(seconds=10)
        assert silence_cutoff(heard + timedelta(seconds=25), 10.0) == heard + timedelta(seconds=15)
