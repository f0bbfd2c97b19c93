"""The localiser map's mapped paths: the mapping drives' poses as polylines that the continuous track follows
instead of the chords between node centres."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse import csr_array

from driftmap.core.localisation.map import LocaliserMap, mapped_paths
from driftmap.core.localisation.track import TRACK_DEFAULT, TrackState
from driftmap.core.localisation.tunnels import snap
from driftmap.errors import BadInputError


def arc(n: int, radius_m: float = 20.0, step_m: float = 0.3) -> np.ndarray:
    """(n, 2) poses along a circle of ``radius_m`` about the origin, ``step_m`` apart, from +x anticlockwise."""
    a = np.arange(n) * step_m / radius_m
    return np.c_[radius_m * np.cos(a), radius_m * np.sin(a)]


class TestMappedPaths:
    def test_vertices_every_step_and_standing_poses_collapse(self) -> None:
        xy = np.r_[np.c_[np.linspace(0, 10, 41), np.zeros(41)], np.tile([[10.0, 0.0]], (20, 1))]
        vertices, segments = mapped_paths(xy, np.array([0, xy.shape[0]]), step_m=1.0)
        assert np.diff(vertices[:, 0]) == pytest.approx(np.ones(10))
        assert segments.tolist() == [[k, k + 1] for k in range(10)]

    def test_chains_gaps_and_missing_poses_are_not_joined(self) -> None:
        xy = np.array([[0, 0], [1, 0], [2, 0], [30, 0], [31, 0], [np.nan, np.nan], [32, 0], [50, 0], [51, 0]])
        vertices, segments = mapped_paths(xy.astype(float), np.array([0, 7, 9]), step_m=1.0, max_gap_m=10.0)
        assert vertices.shape == (9 - 1, 2)
        assert segments.tolist() == [[0, 1], [1, 2], [3, 4], [6, 7]]

    def test_a_track_on_a_curve_is_put_on_the_curve_not_the_chord(self) -> None:
        poses = arc(200)  # 60 m (3 rad) of a 20 m radius bend
        vertices, segments = mapped_paths(poses, np.array([0, poses.shape[0]]))
        lm = LocaliserMap(
            thumbs=np.zeros((2, 4, 4), dtype=np.float32),
            node_ptr=np.array([0, 1, 2]),
            centres_m=poses[[0, -1]],
            adjacency_m=csr_array(np.array([[0.0, 60.0], [60.0, 0.0]])),
            max_adjacency_m=100.0,
            edges=np.array([[0, 1]]),
            path_xy_m=vertices,
            path_segments=segments,
        )
        mid = 1.5  # the bend's middle, radians
        off = 20.5 * np.array([math.cos(mid), math.sin(mid)])  # 0.5 m outside it, 20 m from the chord
        track = TrackState(np.r_[off, mid + math.pi / 2], 1.0, 1.0, 0.0)
        near = lm.path_near(off, TRACK_DEFAULT.snap_max_m)
        assert 0 < near.shape[0] < segments.shape[0]
        on = snap(track, lm.path_xy_m, near, True, TRACK_DEFAULT, steered=True)  # type: ignore[arg-type]
        assert math.hypot(*on.wT[:2]) == pytest.approx(20.0, abs=0.01)

    def test_bad_paths_are_refused_naming_the_field(self) -> None:
        with pytest.raises(BadInputError, match="path_segments"):
            LocaliserMap(
                thumbs=np.zeros((1, 4, 4), dtype=np.float32),
                node_ptr=np.array([0, 1]),
                centres_m=np.zeros((1, 2)),
                adjacency_m=csr_array((1, 1)),
                max_adjacency_m=10.0,
                path_xy_m=np.zeros((2, 2)),
                path_segments=np.array([[0, 2]]),
            )
