"""Vehicle motion of the planned drives: coverage, groundings, kinematics, duty cycles, budgets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.sim import SitePlan, plan_site
from driftmap.sim.geometry import heading_at, point_at
from driftmap.sim.params import SIZES, VEHICLE_DEFAULT
from driftmap.sim.routes import Dart, Graph
from driftmap.sim.trajectory import FramePoses

MAX_SPEED_MPS = 7.0
SPEED_TOL_MPS = 0.05  # frame-differencing error
HEADING_TOL_DEG = 5.0  # rear-axle velocity vs heading (crab noise is under 1 deg)
GROUNDING_MAX_M = 1.5  # 0.3 m per axis: 5 sigma radially
BUDGET_TOL = 0.30  # frames within 30 % of the size's budget
MOVING_MPS = 0.3


@pytest.fixture(scope="module", params=["tiny", "small"])
def site(request: pytest.FixtureRequest, tiny_plan: SitePlan) -> SitePlan:
    return tiny_plan if request.param == "tiny" else plan_site(21, "small")


def _rear(p: FramePoses, y_c: float) -> NDArray[np.float64]:
    return np.asarray(p.xy - y_c * np.stack([np.cos(p.yaw), np.sin(p.yaw)], axis=1))


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray((a + np.pi) % (2 * np.pi) - np.pi)


class TestMappingCoverage:
    def test_every_tunnel_in_both_directions(self, site: SitePlan) -> None:
        g = Graph(site.layout, VEHICLE_DEFAULT.turn_max_rad)
        driven = {d for p in site.plans if p.kind == "mapping" for d in p.darts}
        for e in site.layout.edges:
            if g.is_leaf(e.b):  # a dead end: in forward, out in reverse
                assert Dart(e.id, True) in driven
            else:
                assert {Dart(e.id, True), Dart(e.id, False)} <= driven, f"edge {e.id} ({e.kind})"

    def test_every_tunnel_seen_facing_both_ways(self, site: SitePlan) -> None:
        """From the frames: near each through-tunnel's middle the camera faces both ways along it."""
        poses = [p for p, plan in zip(site.poses, site.plans, strict=True) if plan.kind == "mapping"]
        xy = np.concatenate([p.xy for p in poses])
        yaw = np.concatenate([p.yaw for p in poses])
        g = Graph(site.layout, VEHICLE_DEFAULT.turn_max_rad)
        for e in site.layout.edges:
            if g.is_leaf(e.b) or e.length_m < 12.0:
                continue
            mid, along = point_at(e.polyline, e.length_m / 2), heading_at(e.polyline, e.length_m / 2)
            near = np.hypot(*(xy - mid).T) < 3.0
            rel = np.abs(_wrap(yaw[near] - along))
            assert np.any(rel < math.radians(20)) and np.any(rel > math.radians(160)), f"edge {e.id}"


class TestGroundings:
    def test_near_truth_at_stationary_frames(self, site: SitePlan) -> None:
        errors = []
        for plan, p in zip(site.plans, site.poses, strict=True):
            if plan.kind != "mapping":
                assert not p.groundings
                continue
            assert len(p.groundings) >= 2
            for f, x, y in p.groundings:
                errors.append(math.hypot(x - p.xy[f, 0], y - p.xy[f, 1]))
                lo, hi = max(f - 2, 0), min(f + 3, len(p.t))
                assert np.ptp(p.xy[lo:hi], axis=0).max() < 1e-6  # the vehicle stands still
        assert max(errors) < GROUNDING_MAX_M
        assert 0.15 < float(np.mean(errors)) < 0.6  # ~0.3 m per axis

    def test_grounded_at_every_dead_end(self, site: SitePlan) -> None:
        grounded = np.array([(x, y) for p in site.poses for _, x, y in p.groundings])
        standoff = VEHICLE_DEFAULT.deadend_standoff_m
        for n in site.layout.nodes:
            if n.kind != "junction":
                dist = np.hypot(*(grounded - np.asarray(n.xy)).T)
                assert dist.min() < standoff + 1.5, n.name


class TestKinematics:
    def test_time_speed_and_heading(self, site: SitePlan) -> None:
        y_c = site.rig.params.y_c_m
        for p in site.poses:
            dt = np.diff(p.t)
            assert np.all(dt > 0)
            step = np.diff(_rear(p, y_c), axis=0)
            speed = np.hypot(*step.T) / dt
            assert speed.max() <= MAX_SPEED_MPS + SPEED_TOL_MPS
            moving = speed > MOVING_MPS
            travel = np.arctan2(step[moving, 1], step[moving, 0])
            rel = np.abs(_wrap(travel - p.yaw[:-1][moving]))
            off = np.minimum(rel, np.pi - rel)  # forward or reversing
            assert np.degrees(off.max()) < HEADING_TOL_DEG

    def test_yaw_is_smooth(self, site: SitePlan) -> None:
        for p in site.poses:
            assert np.abs(_wrap(np.diff(p.yaw))).max() < 0.12  # rad per frame at 10 Hz

    def test_accelerations_are_bounded(self, site: SitePlan) -> None:
        y_c = site.rig.params.y_c_m
        for p in site.poses:
            v = np.hypot(*np.diff(_rear(p, y_c), axis=0).T) / np.diff(p.t)
            assert np.abs(np.diff(v) / np.diff(p.t)[1:]).max() < 2.0  # m/s^2, limits 1.0 / 1.5


class TestDutyCycles:
    def test_localisation_drives_haul_between_drawpoints_and_dump(self, site: SitePlan) -> None:
        y_c = site.rig.params.y_c_m
        dump = np.asarray(site.layout.nodes_of_kind("dump")[0].xy)
        dps = np.array([n.xy for n in site.layout.nodes_of_kind("drawpoint")])
        locs = [
            (plan, p) for plan, p in zip(site.plans, site.poses, strict=True) if plan.kind == "localisation"
        ]
        assert locs
        for plan, p in locs:
            near_dump = np.hypot(*(p.xy - dump).T).min()
            near_dp = np.min(np.hypot(p.xy[:, None, 0] - dps[None, :, 0], p.xy[:, None, 1] - dps[None, :, 1]))
            assert near_dump < 8.0 and near_dp < 8.0, plan.name
            step = np.diff(_rear(p, y_c), axis=0)
            along = step[:, 0] * np.cos(p.yaw[:-1]) + step[:, 1] * np.sin(p.yaw[:-1])
            assert (along < -0.05).sum() > 10 and (along > 0.05).sum() > 10  # reverses and drives forward
            still = np.hypot(*step.T) < 1e-9
            assert still.sum() >= 20  # stops (digging, tipping, waiting)
        speeds = np.concatenate([np.hypot(*np.diff(_rear(p, y_c), axis=0).T) / np.diff(p.t) for _, p in locs])
        assert speeds.max() > 3.0

    def test_drives_are_named_and_ordered(self, site: SitePlan) -> None:
        kinds = [p.kind for p in site.plans]
        n_map = kinds.count("mapping")
        assert n_map >= 2 and kinds == ["mapping"] * n_map + ["localisation"] * (len(kinds) - n_map)
        assert len({p.name for p in site.plans}) == len(site.plans)


class TestBudget:
    @pytest.mark.parametrize("size", ["small", "medium", "large"])
    def test_frame_budget(self, size: str) -> None:
        site = plan_site(1, size)
        total = sum(len(p.t) for p in site.poses)
        budget = SIZES[size].frame_budget
        assert abs(total - budget) <= BUDGET_TOL * budget, total
