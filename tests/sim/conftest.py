"""Shared fixtures of the simulator tests: one planned and one written tiny site per session."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from driftmap.sim import SimulationSummary, SitePlan, plan_site, simulate_site
from driftmap.sim.ride import RIDE_NONE

SEED = 5
WRITTEN_FRAMES = 160  # frames kept per written drive; the plan-level tests check whole drives


@dataclass(frozen=True)
class WrittenSite:
    path: Path
    summary: SimulationSummary


@pytest.fixture(scope="session")
def tiny_plan() -> SitePlan:
    """The tiny site's layout and drive plans (no rendering)."""
    return plan_site(SEED, "tiny")


@pytest.fixture(scope="session")
def tiny_site(tmp_path_factory: pytest.TempPathFactory) -> WrittenSite:
    """The tiny site written to disk (first frames of every drive), obscured copies included.

    Rendered with a perfect rig (no bounce, blur or calibration error) so pixels agree exactly with truth.
    """
    out = tmp_path_factory.mktemp("sim") / "site"
    summary = simulate_site(out, seed=SEED, size="tiny", max_frames_per_drive=WRITTEN_FRAMES, ride=RIDE_NONE)
    return WrittenSite(out, summary)
