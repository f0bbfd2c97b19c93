"""The localiser's query frames through a lens: taken in the camera's thumbnail view, as the map's were."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.images import preprocess
from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.params import IMAGES_DEFAULT
from driftmap.core.imaging.views import thumbnails
from driftmap.core.localisation.localiser import Localiser
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.topomap.distances import shortest_paths
from tests.core.imaging.boards import FISHEYE, SIZE, render_wall, wall_texture

N_NODES = 4
SPACING_M = 5.0
CAMERA = CameraModel(SIZE[0], SIZE[1], (200, 300, 240, 120), 0.01, 0.01, 1.5, 3.0, lens=FISHEYE)


def lens_frames() -> NDArray[np.uint8]:
    """(N_NODES, H, W) uint8 one fisheye frame per node: a wall of its own texture."""
    return np.stack([render_wall(FISHEYE, wall_texture(seed=10 + j)) for j in range(N_NODES)])


@pytest.fixture(scope="module")
def frames() -> NDArray[np.uint8]:
    return lens_frames()


def corridor(thumbs: NDArray[np.float32]) -> LocaliserMap:
    """A straight corridor of N_NODES nodes, one reference thumbnail each."""
    edges = np.stack([np.arange(N_NODES - 1), np.arange(1, N_NODES)], axis=1).astype(np.int64)
    return LocaliserMap(
        thumbs=thumbs,
        node_ptr=np.arange(N_NODES + 1, dtype=np.int64),
        centres_m=np.column_stack([np.arange(N_NODES) * SPACING_M, np.zeros(N_NODES)]),
        adjacency_m=shortest_paths(N_NODES, edges, np.full(N_NODES - 1, SPACING_M), 50.0),
        max_adjacency_m=50.0,
        edges=edges,
    )


class TestQueryThumbnails:
    @pytest.mark.parametrize("kwargs", [{"lens": FISHEYE}, {"camera": CAMERA}], ids=["lens", "camera's lens"])
    def test_queries_are_taken_in_the_lens_view(
        self, frames: NDArray[np.uint8], kwargs: dict[str, object]
    ) -> None:
        lmap = corridor(thumbnails(frames, IMAGES_DEFAULT, FISHEYE))
        loc = Localiser(lmap, single_image=True, **kwargs)  # type: ignore[arg-type]
        np.testing.assert_array_equal(loc.thumbnail(frames[2]), lmap.thumbs[2])

    def test_without_a_lens_queries_are_the_recorded_frames(self, frames: NDArray[np.uint8]) -> None:
        plain = dataclasses.replace(CAMERA, lens=None)
        loc = Localiser(corridor(preprocess(frames, IMAGES_DEFAULT)), single_image=True, camera=plain)
        assert loc.lens is None
        np.testing.assert_array_equal(loc.thumbnail(frames[1]), preprocess(frames[1], IMAGES_DEFAULT))

    def test_an_explicit_lens_wins(self) -> None:
        other = Lens("pinhole", FISHEYE.K, (0.0, 0.0, 0.0, 0.0))
        thumbs = np.zeros((N_NODES, 32, 64), dtype=np.float32)
        assert Localiser(corridor(thumbs), single_image=True, camera=CAMERA, lens=other).lens == other
