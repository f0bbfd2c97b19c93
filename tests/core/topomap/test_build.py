"""Map compression (paper III-A-4) and the sparse adjacency behind the HMM transitions (III-B, eq. 9-10)."""

from __future__ import annotations

import io
import itertools
import math
from typing import ClassVar

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from driftmap.core.topomap.build import build_topomap
from driftmap.core.topomap.model import (
    TOPOMAP_FAST,
    TOPOMAP_PAPER,
    NodeFrames,
    TopoMap,
    TopoMapParams,
    per_node,
)
from driftmap.errors import BadInputError

SPACING_TOL_M = 0.6  # node spacing along a straight tunnel, vs N = 5 m (frames every 0.25 m, 1-2 m passes)
PATH_TOL_M = 1.5  # shortest-path length vs the length along the tunnel centre line
LONG = TopoMapParams(max_adjacency_m=200.0)  # TOPOMAP_PAPER with every path of the test sites stored

F64 = NDArray[np.float64]


def drive(
    waypoints: list[tuple[float, float]],
    *,
    lateral_m: float = 0.0,
    noise_m: float = 0.1,
    step_m: float = 0.25,
    seed: int = 0,
    backwards: bool = False,
) -> F64:
    """(N, 3) poses [x, y, yaw] every ``step_m`` along a polyline, offset ``lateral_m`` to the left.

    ``backwards``: the vehicle reverses along the polyline, so it faces against the direction of travel.
    """
    pts = np.asarray(waypoints, dtype=np.float64)
    out = []
    for a, b in itertools.pairwise(pts):
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        s = np.arange(0.0, length, step_m)
        left = np.array([-u[1], u[0]])
        xy = a + s[:, None] * u + lateral_m * left
        yaw = math.atan2(u[1], u[0]) + (math.pi if backwards else 0.0)
        out.append(np.column_stack([xy, np.full(s.size, yaw)]))
    out.append(np.array([[*pts[-1], out[-1][-1, 2]]]))
    poses = np.concatenate(out)
    rng = np.random.default_rng(seed)
    poses[:, :2] += rng.normal(0.0, noise_m, (poses.shape[0], 2))
    poses[:, 2] = (poses[:, 2] + math.pi) % (2 * math.pi) - math.pi
    return poses


def stop_at(poses: F64, row: int, frames: int, jitter_m: float = 0.01, seed: int = 1) -> F64:
    """Insert ``frames`` stationary poses (small jitter) after ``row``."""
    rng = np.random.default_rng(seed)
    still = np.repeat(poses[row : row + 1], frames, axis=0)
    still[:, :2] += rng.normal(0.0, jitter_m, (frames, 2))
    return np.concatenate([poses[: row + 1], still, poses[row + 1 :]])


def node_at(m: TopoMap, x: float, y: float) -> int:
    node, dist = m.nearest_node(x, y)
    assert dist < m.params.merge_radius_m + 1.0
    return node


def straight_both_ways() -> TopoMap:
    east = drive([(0, 0), (100, 0)], lateral_m=-0.8, seed=1)
    west = drive([(100, 0), (0, 0)], lateral_m=-0.8, seed=2)
    return build_topomap([east, west], params=LONG)


class TestStraightTunnel:
    def test_one_node_every_spacing(self) -> None:
        m = straight_both_ways()
        assert 20 <= m.n_nodes <= 22
        xs = np.sort(m.centres_m[:, 0])
        assert np.all(np.abs(np.diff(xs) - 5.0) < SPACING_TOL_M)
        inner = m.degree() == 2  # both lanes averaged onto the centre line (an end node may see one lane)
        assert np.all(np.abs(m.centres_m[inner, 1]) < 0.5)

    def test_nodes_hold_both_directions(self) -> None:
        m = straight_both_ways()
        for node in range(m.n_nodes):
            refs, dist = m.members(node)
            assert set(refs[:, 0]) == {0, 1} and dist.max() < TOPOMAP_PAPER.spacing_m
            chosen = m.chosen_frames(node)
            assert set(chosen[:, 0]) == {0, 1} and len(chosen) <= TOPOMAP_PAPER.frames_per_node
            heads = np.sort(np.abs(m.headings(node)))
            assert len(heads) == 2 and heads[0] < 0.2 and heads[1] > math.pi - 0.2

    def test_chain_graph_distances(self) -> None:
        m = straight_both_ways()
        first = node_at(m, 0, 0)
        assert m.degree().max() == 2 and len(m.edges) == m.n_nodes - 1
        for k in range(m.n_nodes):
            assert m.distance_m(first, node_at(m, 5.0 * k, 0)) == pytest.approx(5.0 * k, abs=PATH_TOL_M)

    def test_paths_beyond_the_stored_maximum_are_infinite(self) -> None:
        east = drive([(0, 0), (100, 0)], seed=1)
        m = build_topomap([east], params=TOPOMAP_PAPER)
        assert m.distance_m(node_at(m, 0, 0), node_at(m, 45, 0)) == pytest.approx(45.0, abs=PATH_TOL_M)
        assert m.distance_m(node_at(m, 0, 0), node_at(m, 60, 0)) == math.inf
        assert m.adjacency_m.data.max() <= TOPOMAP_PAPER.max_adjacency_m


class TestJunction:
    @pytest.mark.parametrize("branch_x", [50.0, 52.5])  # on a node, and halfway between two
    def test_t_junction(self, branch_x: float) -> None:
        chains = [
            drive([(0, 0), (100, 0)], lateral_m=-0.8, seed=1),
            drive([(100, 0), (0, 0)], lateral_m=-0.8, seed=2),
            drive([(0, 0), (branch_x, 0), (branch_x, 40)], lateral_m=-0.8, seed=3),
            drive([(branch_x, 40), (branch_x, 0), (100, 0)], lateral_m=-0.8, seed=4),
        ]
        m = build_topomap(chains, params=LONG)
        assert m.degree().max() >= 3
        assert m.edge_length_m.max() < TOPOMAP_PAPER.spacing_m + TOPOMAP_PAPER.merge_radius_m
        west, east, north = node_at(m, 0, 0), node_at(m, 100, 0), node_at(m, branch_x, 40)
        assert m.distance_m(west, north) == pytest.approx(branch_x + 40, abs=2 * PATH_TOL_M)
        assert m.distance_m(east, north) == pytest.approx(100 - branch_x + 40, abs=2 * PATH_TOL_M)
        assert m.distance_m(west, east) == pytest.approx(100, abs=2 * PATH_TOL_M)


class TestLoop:
    RECT: ClassVar[list[tuple[float, float]]] = [
        (0.0, 0.0),
        (60.0, 0.0),
        (60.0, 20.0),
        (0.0, 20.0),
        (0.0, 0.0),
        (10.0, 0.0),
    ]

    def test_loop_closes_and_paths_take_the_short_way(self) -> None:
        ccw = drive(self.RECT, lateral_m=-0.8, seed=5)
        cw = drive(self.RECT[::-1], lateral_m=-0.8, seed=6)
        m = build_topomap([ccw, cw], params=LONG)
        start, top_left = node_at(m, 0, 0), node_at(m, 0, 20)
        assert m.distance_m(start, top_left) == pytest.approx(20.0, abs=PATH_TOL_M)
        assert m.distance_m(node_at(m, 10, 0), node_at(m, 10, 20)) == pytest.approx(40.0, abs=2 * PATH_TOL_M)
        assert len(m.edges) == m.n_nodes  # one cycle: closed, no duplicate stub
        assert m.degree().max() == 2

    def test_wall_rule_keeps_a_thin_wall_apart(self) -> None:
        # East along y=0, round a hairpin, back west along y=2.2: a thin wall between the two tunnels.
        path = [(0.0, 0.0), (20.0, 0.0), (20.0, 12.0), (16.0, 12.0), (16.0, 2.2), (0.0, 2.2)]
        poses = drive(path, noise_m=0.05, seed=6)
        walled = build_topomap([poses], params=TopoMapParams(max_adjacency_m=200.0, wall_detour_m=80.0))
        a, b = node_at(walled, 5, 0), node_at(walled, 5, 2.2)
        assert a != b and walled.distance_m(a, b) > 40.0  # only round the hairpin
        merged = build_topomap([poses], params=TopoMapParams(max_adjacency_m=200.0, wall_detour_m=1e-3))
        assert merged.distance_m(node_at(merged, 5, 0), node_at(merged, 5, 2.2)) < 6.0


class TestStopsAndReversals:
    def test_a_long_stop_makes_one_node(self) -> None:
        moving = drive([(0, 0), (30, 0)], seed=7)
        stopped = stop_at(moving, 50, 500)
        plain, m = build_topomap([moving]), build_topomap([stopped])
        assert m.n_nodes == plain.n_nodes
        assert len(set(m.frame_nodes(0)[51:551].tolist())) == 1
        np.testing.assert_allclose(m.centres_m, plain.centres_m, atol=0.3)

    def test_reversing_makes_no_self_loops_or_jumps(self) -> None:
        forward = drive([(0, 0), (30, 0)], seed=8)
        back = drive([(30, 0), (12, 0)], seed=9, backwards=True)
        again = drive([(12, 0), (50, 0)], seed=10)
        m = build_topomap([np.concatenate([forward, back, again])], params=LONG)
        assert 10 <= m.n_nodes <= 12
        assert np.all(m.edges[:, 0] != m.edges[:, 1])
        assert m.degree().max() == 2 and m.edge_length_m.max() < TOPOMAP_PAPER.spacing_m + 1.0
        assert m.distance_m(node_at(m, 0, 0), node_at(m, 50, 0)) == pytest.approx(50.0, abs=PATH_TOL_M)

    def test_a_gap_in_the_data_adds_no_edge(self) -> None:
        a, b = drive([(0, 0), (20, 0)], seed=11), drive([(60, 0), (80, 0)], seed=12)
        m = build_topomap([np.concatenate([a, b])])
        assert m.edge_length_m.max() < TOPOMAP_PAPER.spacing_m + 1.0
        assert m.distance_m(node_at(m, 20, 0), node_at(m, 60, 0)) == math.inf


class TestTransitions:
    def test_columns_sum_to_one_and_respect_a_t(self) -> None:
        m = straight_both_ways()
        a_t = 7.0
        pi = m.transition_matrix(a_t).toarray()
        np.testing.assert_allclose(pi.sum(axis=0), 1.0)
        for x in range(m.n_nodes):
            reach = {y for y in range(m.n_nodes) if m.distance_m(x, y) < a_t}
            assert set(np.nonzero(pi[:, x])[0].tolist()) == reach and x in reach
            nodes, dist = m.neighbours_within(x, a_t)
            assert nodes[0] == x and dist[0] == 0.0 and set(nodes.tolist()) == reach

    def test_a_t_beyond_the_stored_paths_is_refused(self) -> None:
        m = build_topomap([drive([(0, 0), (30, 0)])], params=TOPOMAP_FAST)
        with pytest.raises(BadInputError):
            m.transition_matrix(TOPOMAP_FAST.max_adjacency_m + 1.0)
        with pytest.raises(BadInputError):
            m.transition_matrix(0.0)


class TestFramesAndLookups:
    def test_quality_and_frame_ids_steer_the_choice(self) -> None:
        poses = drive([(0, 0), (20, 0)], noise_m=0.0)
        ids = np.arange(poses.shape[0]) + 1000
        quality = np.zeros(poses.shape[0])
        quality[::7] = 1.0  # every 7th frame is sharp: worth 1 m of distance from the centre
        m = build_topomap([poses], frame_ids=[ids], quality=[quality])
        for node in range(m.n_nodes):
            _, row, fid = m.chosen_frames(node)[0]
            assert quality[row] == 1.0 and fid == row + 1000

    def test_selector_hook_sees_every_member(self) -> None:
        seen: list[int] = []

        def nearest_two(cands: NodeFrames, k: int) -> NDArray[np.int64]:
            seen.append(cands.node)
            assert cands.xy_m.shape == (cands.chain.size, 2) and cands.dist_m.min() < 2.5
            return np.argsort(cands.dist_m)[: min(k, 2)].astype(np.int64)

        m = build_topomap([drive([(0, 0), (30, 0)])], select_frames=per_node(nearest_two))
        assert seen == list(range(m.n_nodes))
        assert all(len(m.chosen_frames(n)) == 2 for n in range(m.n_nodes))

    def test_a_bad_selector_is_reported(self) -> None:
        with pytest.raises(BadInputError, match="select_frames"):
            build_topomap([drive([(0, 0), (10, 0)])], select_frames=per_node(lambda c, k: np.arange(k + 1)))
        with pytest.raises(BadInputError, match="select_frames"):
            build_topomap([drive([(0, 0), (10, 0)])], select_frames=per_node(lambda c, k: np.array([-1])))
        with pytest.raises(BadInputError, match="answered 0 of"):
            build_topomap([drive([(0, 0), (10, 0)])], select_frames=lambda nodes, k: [])

    def test_nearest_node_and_frame_nodes(self) -> None:
        m = straight_both_ways()
        node, dist = m.nearest_node(42.0, 0.4)
        assert abs(m.centres_m[node, 0] - 42.0) <= 2.5 + SPACING_TOL_M and dist < 3.0
        per_frame = m.frame_nodes(1)
        assert per_frame.shape == (m.chain_ptr[2] - m.chain_ptr[1],)
        assert node_at(m, 100, 0) == per_frame[0] and node_at(m, 0, 0) == per_frame[-1]


class TestSerialisation:
    def test_round_trip(self) -> None:
        m = straight_both_ways()
        arrays = m.to_arrays()
        assert all(isinstance(v, np.ndarray) for v in arrays.values())
        back = TopoMap.from_arrays(dict(arrays))
        assert back.params == m.params
        for key, value in back.to_arrays().items():
            np.testing.assert_array_equal(value, arrays[key], err_msg=key)
        assert (back.adjacency_m != m.adjacency_m).nnz == 0
        np.testing.assert_array_equal(
            back.transition_matrix(7.0).toarray(), m.transition_matrix(7.0).toarray()
        )

    def test_through_an_npz_blob(self) -> None:
        m = straight_both_ways()
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **m.to_arrays())  # type: ignore[arg-type]
        with np.load(io.BytesIO(buffer.getvalue())) as stored:
            back = TopoMap.from_arrays({k: stored[k] for k in stored.files})
        assert back.params == m.params and back.n_nodes == m.n_nodes
        np.testing.assert_array_equal(back.chosen_frames(3), m.chosen_frames(3))

    def test_missing_array_names_the_field(self) -> None:
        arrays = straight_both_ways().to_arrays()
        del arrays["edges"]
        with pytest.raises(BadInputError, match="edges"):
            TopoMap.from_arrays(arrays)


class TestInputs:
    def test_bad_shapes_are_reported(self) -> None:
        with pytest.raises(BadInputError, match="poses_sTv"):
            build_topomap([np.zeros((5, 2))])
        with pytest.raises(BadInputError, match="frame_ids"):
            build_topomap([np.zeros((5, 3))], frame_ids=[np.arange(4)])
        with pytest.raises(BadInputError, match="merge_radius_m"):
            TopoMapParams(spacing_m=5.0, merge_radius_m=6.0)

    def test_no_drives_make_an_empty_map(self) -> None:
        m = build_topomap([np.zeros((0, 3))])
        assert m.n_nodes == 0 and m.adjacency_m.shape == (0, 0)


@st.composite
def site(draw: st.DrawFn) -> list[F64]:
    chains = []
    for c in range(draw(st.integers(1, 3))):
        n = draw(st.integers(2, 5))
        pts = draw(st.lists(st.tuples(st.floats(0, 60), st.floats(0, 60)), min_size=n, max_size=n))
        pts = [p for i, p in enumerate(pts) if i == 0 or math.dist(p, pts[i - 1]) > 0.5]
        if len(pts) < 2:
            pts = [(0.0, 0.0), (10.0, 0.0)]
        step = draw(st.one_of(st.floats(0.1, 2.0), st.floats(2.0, 12.0)))  # long steps skip nodes
        poses = drive(pts, step_m=step, noise_m=draw(st.floats(0.0, 0.5)), seed=c)
        if draw(st.booleans()):
            poses = stop_at(poses, draw(st.integers(0, poses.shape[0] - 1)), draw(st.integers(1, 50)))
        chains.append(poses)
    return chains


class TestProperties:
    @settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(chains=site(), params=st.sampled_from([TOPOMAP_PAPER, TOPOMAP_FAST]))
    def test_frames_near_their_node_and_symmetric_adjacency(
        self, chains: list[F64], params: TopoMapParams
    ) -> None:
        m = build_topomap(chains, params=params)
        xy = np.concatenate(chains)[:, :2]
        dist = np.linalg.norm(xy - m.centres_m[m.frame_node], axis=1)
        np.testing.assert_allclose(dist, m.frame_dist_m)
        assert dist.max() <= params.merge_radius_m + params.spacing_m
        a = m.adjacency_m
        assert (a != a.T).nnz == 0 and np.all(a.diagonal() == 0) and np.all(a.data > 0)
        assert all(m.distance_m(i, i) == 0.0 for i in range(m.n_nodes))
        np.testing.assert_allclose(m.transition_matrix(params.spacing_m).sum(axis=0), 1.0)
        assert np.all(m.edges[:, 0] < m.edges[:, 1])
        for n in range(m.n_nodes):
            chosen, members = m.chosen_frames(n), m.members(n)[0]
            assert len(chosen) <= params.frames_per_node and (len(chosen) > 0) == (len(members) > 0)
