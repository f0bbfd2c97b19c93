"""Place recognition on outside data: metrics, single-image matching and the route HMM on hand-made cases."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from driftmap.core.place_recognition import metrics, route_filter
from driftmap.core.place_recognition import route as vpr_route
from driftmap.core.place_recognition import single as vpr
from driftmap.core.place_recognition.route_filter import (
    ROUTE_ANY_SPEED,
    ROUTE_DEFAULT,
    ROUTE_ONLINE,
    RouteFilter,
    RouteParams,
    reference_stats,
    route_transitions,
    smooth_route,
)
from driftmap.errors import BadInputError
from tests.outside_data import SHARED_DATA
from tests.vpr_factory import noisy, textures

DATA = SHARED_DATA


class TestMetrics:
    def test_hand_made_sweep(self) -> None:
        # scores 0.9 (right), 0.8 (wrong), 0.7 (right), 0.6 (right); 5 recallable queries (one never matched)
        score = np.array([0.9, 0.8, 0.7, 0.6, -np.inf])
        correct = np.array([True, False, True, True, False])
        curve = metrics.pr_curve(score, correct, recallable=5)
        np.testing.assert_allclose(curve.thresholds, [0.9, 0.8, 0.7, 0.6])
        np.testing.assert_allclose(curve.precision, [1.0, 0.5, 2 / 3, 3 / 4])
        np.testing.assert_allclose(curve.recall, [0.2, 0.2, 0.4, 0.6])
        assert curve.auc == pytest.approx(0.2 * 1.0 + 0.0 * 0.5 + 0.2 * 2 / 3 + 0.2 * 3 / 4)
        assert curve.recall_at_full_precision == pytest.approx(0.2)

    def test_ties_enter_together(self) -> None:
        # a wrong and a right match with the same score: no threshold separates them
        curve = metrics.pr_curve(np.array([0.5, 0.5]), np.array([True, False]), recallable=2)
        np.testing.assert_allclose(curve.precision, [0.5])
        assert curve.recall_at_full_precision == 0.0

    def test_evaluate_matches(self) -> None:
        gt = np.zeros((3, 4), dtype=bool)
        gt[0, 0] = gt[1, 1] = gt[1, 2] = True  # query 2 has no acceptable match
        result, _ = metrics.evaluate_matches(np.array([0, 2, 3]), np.array([0.3, 0.2, 0.9]), gt)
        assert result.recall_at_1 == 1.0
        assert (result.queries, result.recallable) == (3, 2)
        assert result.recall_at_full_precision == 0.0  # the most confident match (query 2) is wrong

    def test_bad_input(self) -> None:
        with pytest.raises(BadInputError):
            metrics.match_correct(np.array([5]), np.ones((1, 2), dtype=bool))
        with pytest.raises(BadInputError):
            metrics.pr_curve(np.array([1.0]), np.array([True]), recallable=0)


class TestSingleImage:
    def test_thumbnail_keeps_aspect(self) -> None:
        assert vpr.thumbnail_params((120, 160)).size_px == (64, 48)
        assert vpr.thumbnail_params((32, 64)).size_px == (64, 32)
        assert vpr.thumbnail_params((10, 20)).size_px == (20, 10)  # never enlarged

    def test_match_single_scores(self) -> None:
        d = np.array([[0.5, 1.0, 1.0, np.inf], [1.0, 1.0, 1.0, 1.0]], dtype=np.float32)
        m = vpr.match_single(d)
        assert m.db_index.tolist() == [0, 0]
        np.testing.assert_allclose(m.score, [0.5, 0.0])  # 1 - d_best / median of the finite scores

    def test_noisy_views_find_their_place(self) -> None:
        db = textures(12)
        query = noisy(db, 10.0, seed=1)
        for method in vpr.METHODS:
            m = vpr_route.recognise_places(query, db, method)
            assert m.db_index.tolist() == list(range(12))

    def test_sesame_leaves_a_dark_reference_out(self) -> None:
        db = textures(6)
        db[3] = 2  # a black frame: patch-normalises to zeros and would be near every query
        prepared = vpr.prepare_images(db, "sesame")
        assert prepared.usable.tolist() == [True, True, True, False, True, True]
        d = vpr.distance_matrix(vpr.prepare_images(noisy(db, 5.0, 2), "sesame"), prepared)
        assert np.isinf(d[:, 3]).all() and np.isfinite(np.delete(d, 3, axis=1)).all()
        plain = vpr.distance_matrix(vpr.prepare_images(db, "sad"), vpr.prepare_images(db, "sad"))
        assert np.isfinite(plain).all()

    def test_bad_input(self) -> None:
        with pytest.raises(BadInputError, match="uint8"):
            vpr.prepare_images(np.zeros((2, 8, 8), dtype=np.float32), "sad")
        with pytest.raises(BadInputError, match="method"):
            vpr.prepare_images(np.zeros((2, 8, 8), dtype=np.uint8), "orb")  # type: ignore[arg-type]
        wide, square = (
            vpr.prepare_images(textures(2), "sad"),
            vpr.prepare_images(textures(2, shape=(32, 32)), "sad"),
        )
        with pytest.raises(BadInputError, match="aspect"):
            vpr.distance_matrix(wide, square)


class TestRouteHmm:
    def test_transitions(self) -> None:
        pi = route_transitions(6).toarray()  # forward, reach 2
        assert pi[2:5, 2].tolist() == pytest.approx([1 / 3] * 3) and pi[:2, 2].sum() == 0
        np.testing.assert_allclose(pi.sum(axis=0), [1, 1, 1, 1, 2 / 3, 1 / 3])  # moves past the end leave
        both = route_transitions(6, RouteParams(direction="both", reach_frames=1)).toarray()
        np.testing.assert_allclose(both, both.T)

    def test_reference_stats_exclude_neighbours(self) -> None:
        d = np.array([[0.0, 0.1, 2.0, 2.0, 4.0, 6.0], [3.0, 3.0, 1.0, 0.0, 0.2, 2.0]], dtype=np.float32)
        m, s = reference_stats(d, np.array([0, 3]), exclude_frames=1)
        # sample 0 counts for columns 2..5, sample 3 for columns 0, 1 and 5 only
        np.testing.assert_allclose(m, [3.0, 3.0, 2.0, 2.0, 4.0, 4.0])
        assert s[5] == pytest.approx(1.4826 * 2.0) and np.all(s > 0)

    def test_chain_follows_the_query_through_a_misleading_frame(self) -> None:
        n, start = 30, 4
        rng = np.random.default_rng(0)
        filt = RouteFilter(np.ones(n), np.full(n, 0.1))
        truth = [min(n - 1, start + k) for k in range(20)]
        best = []
        for k, j in enumerate(truth):
            d = 1.0 + 0.05 * rng.standard_normal(n)
            d[j] = 0.6  # z = 4 at the true place
            if k == 10:
                d[j], d[25] = 1.0, 0.4  # one frame: the true place looks ordinary, a far one looks perfect
            best.append(filt.step(d)[0])
        # the misleading frame keeps the belief where the route predicts it (within a frame), not at 25
        assert abs(best[10] - truth[10]) <= 1
        assert best[3:10] + best[11:] == truth[3:10] + truth[11:]

    def test_fractional_speed_splits_mass(self) -> None:
        mass = np.zeros(6)
        mass[1] = 1.0
        np.testing.assert_allclose(route_filter._shift(mass, 1.5), [0, 0, 0.5, 0.5, 0, 0])
        np.testing.assert_allclose(route_filter._shift(mass, 5.0), np.zeros(6))  # past the end: leaves

    def test_tracked_speed_follows_a_fast_query(self) -> None:
        n, speed = 120, 3
        truth = [2 + speed * k for k in range(35)]
        filters = {
            "fixed": RouteFilter(np.ones(n), np.full(n, 0.1)),
            "tracked": RouteFilter(np.ones(n), np.full(n, 0.1), ROUTE_ANY_SPEED),
        }
        best: dict[str, list[int]] = {name: [] for name in filters}
        rng = np.random.default_rng(1)
        for j in truth:
            d = 1.0 + 0.05 * rng.standard_normal(n)
            d[j] = 0.75  # z = 2.5: clear, but not enough to jump against the prior every frame
            for name, filt in filters.items():
                best[name].append(filt.step(d)[0])
        assert best["tracked"][5:] == truth[5:]
        assert np.isclose(filters["tracked"].place_belief.sum(), 1.0)
        # the fixed kernel moves at most 2 references a frame: it keeps losing the query
        assert sum(b != t for b, t in zip(best["fixed"][5:], truth[5:], strict=True)) >= 10

    def test_route_where_single_images_fail(self) -> None:
        db = textures(40, seed=3)
        # each query is 80 % an unrelated scene (a changed season, a passing train) over its true place
        query = noisy((0.2 * db + 0.8 * textures(40, seed=9)).astype(np.uint8), 10.0, seed=4)
        single = vpr_route.recognise_places(query, db, "sad")
        assert (single.db_index != np.arange(40)).sum() >= 8
        m = vpr_route.recognise_places(query, db, "sad", temporal=True)
        assert np.abs(m.db_index[5:] - np.arange(5, 40)).max() <= 1
        assert m.score[5:].min() > 0.5


#: forward-backward and brute force agree to rounding (float32 forward beliefs)
POSTERIOR_ATOL = 1e-6


def _dense_transition(filt: RouteFilter, adjoint: bool = False) -> np.ndarray:
    """(S, S) matrix of the filter's linear transition T (column s: T of the unit mass at state s)."""
    shape = filt.belief.shape
    cols = []
    for s in range(filt.belief.size):
        unit = np.zeros(filt.belief.size)
        unit[s] = 1.0
        cols.append(filt.transition(unit.reshape(shape), adjoint=adjoint).ravel())
    return np.stack(cols, axis=1)


#: the transitions smoothing must invert: the default kernel, the paper's symmetric one, tracked speeds
ROUTES = {
    "forward": ROUTE_DEFAULT,
    "both": RouteParams(direction="both", reach_frames=1),
    "speeds": RouteParams(speeds=(0.0, 1.5, 2.0), speed_change=0.1),
}


class TestSmoothing:
    @pytest.mark.parametrize("name", list(ROUTES))
    def test_adjoint_is_the_transpose(self, name: str) -> None:
        filt = RouteFilter(np.ones(7), np.ones(7), ROUTES[name])
        forward, backward = _dense_transition(filt), _dense_transition(filt, adjoint=True)
        np.testing.assert_allclose(backward, forward.T, atol=1e-15)

    @pytest.mark.parametrize("name", list(ROUTES))
    def test_posterior_equals_brute_force_over_every_path(self, name: str) -> None:
        n, q = 5, 4
        route = replace(ROUTES[name], score_window_frames=0, uniform_mix=0.05)
        rng = np.random.default_rng(7)
        d = rng.uniform(0.5, 1.5, (q, n))
        filt = RouteFilter(np.ones(n), np.full(n, 0.2), route)
        best, raw = smooth_route(d, filt)
        # every path of states through the q frames, weighted by prior x transitions x observations
        fresh = RouteFilter(np.ones(n), np.full(n, 0.2), route)
        t_matrix = _dense_transition(fresh)
        k = fresh.belief.shape[0]
        obs = [np.tile(fresh.observation(row), k) for row in d]
        size = k * n
        marginal = np.zeros((q, n))
        for path in itertools.product(range(size), repeat=q):
            w = obs[0][path[0]] / size
            for i in range(1, q):
                w *= t_matrix[path[i], path[i - 1]] * obs[i][path[i]]
            for i, state in enumerate(path):
                marginal[i, state % n] += w
        marginal /= marginal.sum(axis=1, keepdims=True)
        assert best.tolist() == np.argmax(marginal, axis=1).tolist()
        np.testing.assert_allclose(raw, marginal.max(axis=1), atol=POSTERIOR_ATOL)

    def test_later_frames_settle_an_early_look_alike(self) -> None:
        n, frames, start, twin = 40, 20, 5, 25
        rng = np.random.default_rng(3)
        rows = []
        for t in range(frames):
            d = 1.0 + 0.05 * rng.standard_normal(n)
            d[start + t] = 0.6  # z = 4 at the true place
            if t < 5:
                d[twin + t] = 0.6  # the first five frames also look like another stretch of the route
            rows.append(d)
        d = np.array(rows)
        truth = np.arange(start, start + frames)
        online = vpr_route.match_distances(d, np.ones(n), np.full(n, 0.1), ROUTE_ONLINE)
        smooth = vpr_route.match_distances(d, np.ones(n), np.full(n, 0.1), ROUTE_DEFAULT)
        assert online.score[:5].max() < 0.6  # the filter cannot tell the two stretches apart yet
        assert smooth.db_index.tolist() == truth.tolist()
        assert smooth.score[:5].min() > 0.95


class TestCalibration:
    def test_knots_map_the_score_and_keep_its_order(self) -> None:
        knots = ((0.0, 0.0), (0.5, 0.1), (1.0, 1.0))
        route = replace(ROUTE_DEFAULT, calibration=knots)
        d = 1.0 + 0.05 * np.random.default_rng(4).standard_normal((12, 20))
        d[np.arange(12), np.arange(12) + 4] = 0.7
        raw = vpr_route.match_distances(d, np.ones(20), np.full(20, 0.1), ROUTE_DEFAULT)
        cal = vpr_route.match_distances(d, np.ones(20), np.full(20, 0.1), route)
        np.testing.assert_allclose(cal.score, np.interp(raw.score, *np.array(knots).T))
        assert np.argsort(cal.score, kind="stable").tolist() == np.argsort(raw.score, kind="stable").tolist()

    @pytest.mark.parametrize(
        "knots",
        [
            ((0.0, 0.0), (0.5, 0.5), (0.8, 0.5), (1.0, 1.0)),  # flat: would tie right and wrong matches
            ((0.1, 0.0), (1.0, 1.0)),  # does not start at raw 0
            ((0.0, 0.0), (1.0, 1.2)),  # not a probability
        ],
    )
    def test_bad_knots(self, knots: tuple[tuple[float, float], ...]) -> None:
        with pytest.raises(BadInputError, match="knots"):
            RouteParams(calibration=knots)


@pytest.mark.skipif(not (DATA / "corridor" / "gt.csv").is_file(), reason="shared outside data absent")
def test_corridor_outside_data() -> None:
    """The real corridor (111 vs 111): single-image SAD near the outside reference 0.414, the route far above."""
    from driftmap.formats.place_images import gt_matrix, list_images, read_gray_stack, read_gt_pairs

    folder = DATA / "corridor"
    db_files, q_files = list_images(folder / "db"), list_images(folder / "query")
    gt = gt_matrix(read_gt_pairs(folder / "gt.csv", q_files, db_files), q_files, db_files)
    db, query = read_gray_stack(db_files), read_gray_stack(q_files)
    single = vpr_route.recognise_places(query, db, "sad", params=vpr.VPR_ROUTE)
    route = vpr_route.recognise_places(query, db, "sad", temporal=True, params=vpr.VPR_ROUTE)
    r_single, _ = metrics.evaluate_matches(single.db_index, single.score, gt)
    r_route, _ = metrics.evaluate_matches(route.db_index, route.score, gt)
    assert 0.35 <= r_single.recall_at_1 <= 0.5
    assert r_route.recall_at_1 >= 0.8 and r_route.auc > r_single.auc + 0.3
