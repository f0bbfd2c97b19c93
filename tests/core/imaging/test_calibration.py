"""Tests of driftmap.core.imaging.calibration on boards rendered through known lenses (pinhole and fisheye)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.calibration import (
    MIN_CORNERS,
    MIN_VIEWS,
    Board,
    BoardView,
    board_points,
    calibrate_lens,
    find_board,
)
from driftmap.core.imaging.lens import Lens
from driftmap.errors import BadInputError
from tests.core.imaging.boards import BOARD, CHARUCO, FISHEYE, PINHOLE, SIZE, board_poses, render_view

FOCAL_REL_TOL = 0.01  # issue 21: focal length within 1 %
CENTRE_TOL_PX = 2.0  # principal point within 2 px
RMS_TOL_PX = 0.5  # reprojection RMS
VIEWS = 8
DISTANCE_M = {"pinhole": 0.45, "fisheye": 0.3}


def rendered_views(lens: Lens, board: Board) -> list[BoardView]:
    """The corners found in ``VIEWS`` rendered views of ``board`` through ``lens`` (every view must show it)."""
    poses = board_poses(VIEWS, DISTANCE_M[lens.model], board=board)
    views = [find_board(render_view(lens, r, t, board), board) for r, t in poses]
    assert all(v is not None for v in views)
    return [v for v in views if v is not None]


def assert_recovers(lens: Lens, views: list[BoardView], board: Board) -> None:
    """The issue's targets: focal length within 1 %, principal point within 2 px, RMS at most 0.5 px."""
    result = calibrate_lens(views, board, SIZE, lens.model)
    k, truth = result.lens.matrix(), lens.matrix()
    assert result.lens.model == lens.model
    assert abs(k[0, 0] / truth[0, 0] - 1) < FOCAL_REL_TOL
    assert abs(k[1, 1] / truth[1, 1] - 1) < FOCAL_REL_TOL
    assert np.hypot(k[0, 2] - truth[0, 2], k[1, 2] - truth[1, 2]) < CENTRE_TOL_PX
    assert result.rms_px <= RMS_TOL_PX
    assert len(result.view_rms_px) == VIEWS and max(result.view_rms_px) <= RMS_TOL_PX
    assert len(result.lens.distortion) == (5 if lens.model == "pinhole" else 4)


@pytest.fixture(scope="module", params=[PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
def seen(request: pytest.FixtureRequest) -> tuple[Lens, list[BoardView]]:
    return request.param, rendered_views(request.param, BOARD)


class TestIntrinsics:
    def test_recovers_the_lens(self, seen: tuple[Lens, list[BoardView]]) -> None:
        assert_recovers(*seen, BOARD)

    def test_too_few_views_say_how_many(self, seen: tuple[Lens, list[BoardView]]) -> None:
        lens, views = seen
        with pytest.raises(BadInputError, match=f"found in 2 view.*at least {MIN_VIEWS}") as err:
            calibrate_lens(views[:2], BOARD, SIZE, lens.model)
        assert err.value.field == "images"

    @pytest.mark.parametrize(
        ("ids", "match"), [(np.arange(3), "view 2 has 3 corners"), (np.arange(1, 49), "numbered 1..48")]
    )
    def test_a_view_the_board_cannot_have_is_named(
        self, seen: tuple[Lens, list[BoardView]], ids: NDArray[np.int64], match: str
    ) -> None:
        lens, views = seen
        bad = BoardView(ids, views[1].pixels[: len(ids)])
        with pytest.raises(BadInputError, match=match) as err:
            calibrate_lens([views[0], bad, views[2]], BOARD, SIZE, lens.model)
        assert err.value.field == "images"


@pytest.fixture(scope="module", params=[PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
def charuco_seen(request: pytest.FixtureRequest) -> tuple[Lens, list[BoardView]]:
    """Eight ChArUco views through each lens; the fisheye's boards run off the image in part."""
    return request.param, rendered_views(request.param, CHARUCO)


class TestCharuco:
    def test_recovers_the_lens(self, charuco_seen: tuple[Lens, list[BoardView]]) -> None:
        assert_recovers(*charuco_seen, CHARUCO)

    def test_corners_come_numbered(self, charuco_seen: tuple[Lens, list[BoardView]]) -> None:
        _, views = charuco_seen
        for view in views:
            assert len(np.unique(view.ids)) == len(view.ids) >= MIN_CORNERS
            assert view.ids.max() < CHARUCO.cols * CHARUCO.rows

    def test_a_board_cut_by_the_image_edge_still_counts(self) -> None:
        rvec, tvec = np.zeros(3), np.array([-0.33, -0.05, 0.3])  # the board's left third is out of view
        chess = Board(CHARUCO.cols, CHARUCO.rows, CHARUCO.square_m)
        assert find_board(render_view(PINHOLE, rvec, tvec, chess), chess) is None
        view = find_board(render_view(PINHOLE, rvec, tvec, CHARUCO), CHARUCO)
        assert view is not None and MIN_CORNERS <= len(view.ids) < CHARUCO.cols * CHARUCO.rows
        pts = board_points(CHARUCO)[view.ids]
        proj, _ = cv2.projectPoints(pts, rvec, tvec, PINHOLE.matrix(), PINHOLE.coeffs())
        assert np.max(np.linalg.norm(proj.reshape(-1, 2) - view.pixels, axis=1)) < 0.5  # right numbers

    def test_blank_image_has_no_board(self) -> None:
        assert find_board(np.full((120, 160), 128, np.uint8), CHARUCO) is None

    @pytest.mark.parametrize(
        ("kwargs", "field"),
        [
            ({"marker_m": 0.03}, "marker_m"),
            ({"marker_m": 0.02, "dictionary": "DICT_3X3_9"}, "dictionary"),
            ({"marker_m": 0.02, "dictionary": "DICT_4X4_50", "cols": 11, "rows": 11}, "dictionary"),
        ],
    )
    def test_bad_charuco_board(self, kwargs: dict, field: str) -> None:
        args = {"cols": 9, "rows": 6, "square_m": 0.03, **kwargs}
        with pytest.raises(BadInputError) as err:
            Board(**args)
        assert err.value.field == field


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
