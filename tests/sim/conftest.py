"""Shared fixtures of the simulator tests: one planned and one written tiny site per session."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from driftmap.sim import SimulationSummary, SitePlan, plan_site, simulate_site

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
    """The tiny site written to disk (first frames of every drive), obscured copies included."""
    out = tmp_path_factory.mktemp("sim") / "site"
    return WrittenSite(out, simulate_site(out, seed=SEED, size="tiny", max_frames_per_drive=WRITTEN_FRAMES))
