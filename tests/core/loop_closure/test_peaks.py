"""The top-k local maxima of each row: the looked-in-the-best-groups path equals suppression over whole rows."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.loop_closure.peaks import (
    GROUP,
    NEG,
    SPARE_GROUPS,
    top_k_rows,
    top_local_maxima,
    top_local_maxima_whole_rows,
)

Select = Callable[[NDArray[np.float32], int, int], NDArray[np.int64]]


def _peaks(row: NDArray[np.float32], radius: int) -> list[int]:
    """Columns of the eligible entries no smaller than any within ``radius`` columns."""
    return [
        j
        for j in range(row.size)
        if row[j] > NEG and row[j] >= row[max(0, j - radius) : j + radius + 1].max()
    ]


def _assert_top_peaks(c: NDArray[np.float32], got: NDArray[np.int64], k: int, radius: int) -> None:
    """Each row of ``got``: distinct local maxima, their values the ``k`` largest best first, -1 padding."""
    for row, cols in zip(c, got.tolist(), strict=True):
        peaks = _peaks(row, radius)
        want = sorted((row[j] for j in peaks), reverse=True)[:k]
        found = [j for j in cols if j >= 0]
        assert cols == found + [-1] * (k - len(found))
        assert set(found) <= set(peaks) and len(set(found)) == len(found)
        assert [row[j] for j in found] == want


class TestTopLocalMaxima:
    @pytest.mark.parametrize("cols", [3, GROUP * 6, GROUP * 12 + 17, GROUP * 40])
    @pytest.mark.parametrize("radius", [0, 2])
    @pytest.mark.parametrize("select", [top_local_maxima, top_local_maxima_whole_rows])
    def test_the_largest_local_maxima_best_first(self, cols: int, radius: int, select: Select) -> None:
        rng = np.random.default_rng(cols + radius)
        c = rng.normal(size=(40, cols)).astype(np.float32)
        c[:, ::7] = np.round(c[:, ::7], 1)  # ties, some of them neighbours
        c[5, cols // 2 :] = NEG  # a query's recent window
        c[6] = NEG  # nothing eligible
        c[7, : cols - 3] = NEG  # fewer than k maxima
        _assert_top_peaks(c, select(c, 4, radius), 4, radius)

    def test_peaks_spread_over_many_groups_fall_back_to_whole_rows(self) -> None:
        """A smooth ramp has one local maximum; its best groups hold no k maxima, so the whole row decides."""
        cols = GROUP * (4 + SPARE_GROUPS + 6)
        ramp = np.linspace(0.0, 1.0, cols, dtype=np.float32)
        c = np.stack([ramp, ramp[::-1], np.sin(np.arange(cols, dtype=np.float32) / 40.0)])
        _assert_top_peaks(c, top_local_maxima(c, 4, 2), 4, 2)

    @pytest.mark.parametrize("select", [top_local_maxima, top_local_maxima_whole_rows])
    def test_input_is_not_modified(self, select: Select) -> None:
        c = np.random.default_rng(1).normal(size=(3, GROUP * 20)).astype(np.float32)
        before = c.copy()
        select(c, 4, 2)
        np.testing.assert_array_equal(c, before)


class TestTopKRows:
    def test_is_a_sorted_top_k(self) -> None:
        rng = np.random.default_rng(0)
        for cols in (5, 300, 3001):
            c = rng.normal(size=(7, cols)).astype(np.float32)
            idx, val = top_k_rows(c, 4)
            np.testing.assert_array_equal(idx, np.argsort(-c, axis=1)[:, :4])
            np.testing.assert_array_equal(val, np.take_along_axis(c, idx, axis=1))
