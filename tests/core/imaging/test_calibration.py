"""Tests of driftmap.core.imaging.calibration on boards rendered through known lenses (pinhole and fisheye)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.calibration import MIN_VIEWS, Board, board_points, calibrate_lens, find_board
from driftmap.core.imaging.lens import Lens
from driftmap.errors import BadInputError
from tests.core.imaging.boards import BOARD, FISHEYE, PINHOLE, SIZE, board_poses, render_view

FOCAL_REL_TOL = 0.01  # issue 21: focal length within 1 %
CENTRE_TOL_PX = 2.0  # principal point within 2 px
RMS_TOL_PX = 0.5  # reprojection RMS
VIEWS = 8
DISTANCE_M = {"pinhole": 0.45, "fisheye": 0.3}


@pytest.fixture(scope="module", params=[PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
def seen(request: pytest.FixtureRequest) -> tuple[Lens, list[NDArray[np.float64]]]:
    lens: Lens = request.param
    views = [
        find_board(render_view(lens, r, t), BOARD) for r, t in board_poses(VIEWS, DISTANCE_M[lens.model])
    ]
    assert all(v is not None for v in views)
    return lens, [v for v in views if v is not None]


class TestIntrinsics:
    def test_recovers_the_lens(self, seen: tuple[Lens, list[NDArray[np.float64]]]) -> None:
        lens, views = seen
        result = calibrate_lens(views, BOARD, SIZE, lens.model)
        k, truth = result.lens.matrix(), lens.matrix()
        assert result.lens.model == lens.model
        assert abs(k[0, 0] / truth[0, 0] - 1) < FOCAL_REL_TOL
        assert abs(k[1, 1] / truth[1, 1] - 1) < FOCAL_REL_TOL
        assert np.hypot(k[0, 2] - truth[0, 2], k[1, 2] - truth[1, 2]) < CENTRE_TOL_PX
        assert result.rms_px <= RMS_TOL_PX
        assert len(result.view_rms_px) == VIEWS and max(result.view_rms_px) <= RMS_TOL_PX
        assert len(result.lens.distortion) == (5 if lens.model == "pinhole" else 4)

    def test_too_few_views_say_how_many(self, seen: tuple[Lens, list[NDArray[np.float64]]]) -> None:
        lens, views = seen
        with pytest.raises(BadInputError, match=f"found in 2 view.*at least {MIN_VIEWS}") as err:
            calibrate_lens(views[:2], BOARD, SIZE, lens.model)
        assert err.value.field == "images"

    def test_wrong_corner_count_is_named(self, seen: tuple[Lens, list[NDArray[np.float64]]]) -> None:
        lens, views = seen
        with pytest.raises(BadInputError, match="view 2 has 47 corners"):
            calibrate_lens([views[0], views[1][:-1], views[2]], BOARD, SIZE, lens.model)


class TestBoard:
    def test_blank_image_has_no_board(self) -> None:
        assert find_board(np.full((120, 160), 128, np.uint8), BOARD) is None

    def test_points_row_by_row(self) -> None:
        pts = board_points(Board(3, 2, 0.5))
        assert pts.shape == (6, 3)
        assert np.allclose(pts[:4], [[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [0, 0.5, 0]])

    @pytest.mark.parametrize(
        ("cols", "rows", "square", "field"), [(1, 5, 0.1, "board"), (4, 4, 0.0, "square_m")]
    )
    def test_bad_board(self, cols: int, rows: int, square: float, field: str) -> None:
        with pytest.raises(BadInputError) as err:
            Board(cols, rows, square)
        assert err.value.field == field

    def test_unknown_model(self) -> None:
        with pytest.raises(BadInputError, match="pinhole, fisheye"):
            calibrate_lens([], BOARD, SIZE, "orthographic")  # type: ignore[arg-type]
