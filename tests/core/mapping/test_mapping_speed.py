"""The map build's speed-ups change no result: the lean gradient, packed mask warps, the database's frame
statistics computed in the odometry pass and its pair scores handed to a later build equal their plain
counterparts exactly."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import replace

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.shift_cost import gradient
from driftmap.core.mapping.drive import PreparedSegment
from driftmap.core.mapping.pipeline import (
    MAPPING_FAST,
    MappingDrive,
    flat_offsets,
    join_drives,
    join_segments,
    prepare_drives,
    prepare_segment,
    solve_map,
)
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import _horizon_offset
from driftmap.core.odometry.grid import apply_homography, grid_masks, match_grid, warp_to_grid
from driftmap.core.odometry.params import ODOMETRY_DEFAULT
from driftmap.core.sesame.salient_database import PairScores
from driftmap.core.topomap.database import DatabaseParams, FrameStatsPass, finish_frame_stats, frame_stats
from driftmap.errors import BadInputError
from tests.core.odometry.test_drive import pinhole_camera

CAM = CameraModel(160, 120, (30, 40, 100, 60), 0.01, 0.01, 1.0, 4.0, 1)


def _frames(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([cv2.GaussianBlur(f, (0, 0), 1.5) for f in rng.integers(0, 256, (n, 120, 160), np.uint8)])


def _source(frames: np.ndarray) -> Callable[[], Iterator[np.ndarray]]:
    return lambda: iter(frames)


@pytest.mark.parametrize("shape", [(2, 2), (3, 9), (57, 41)])
def test_gradient_is_numpys_bit_for_bit(shape: tuple[int, int]) -> None:
    img = (np.random.default_rng(1).normal(size=shape) * 50).astype(np.float32)
    g_y, g_x = gradient(img)
    ref_y, ref_x = np.gradient(img)
    assert g_y.dtype == np.float32 and np.array_equal(g_y, ref_y) and np.array_equal(g_x, ref_x)
    with pytest.raises(ValueError):
        gradient(img[:1])


def test_packed_mask_warp_equals_one_warp_per_mask() -> None:
    params = replace(ODOMETRY_DEFAULT, model="linear", linear_patches=(4, 3))  # 12 regions: two packed warps
    setup = match_grid(CAM, params)
    m_rot = setup.px_from_grid @ np.array([[0.99, -0.14, 3.0], [0.14, 0.99, -2.0], [0.0, 0.0, 1.0]])
    regions, valid = grid_masks(CAM, setup, m_rot, 2)
    assert len(regions) == 12
    full = np.ones((CAM.height_px, CAM.width_px), np.uint8)
    for got, mask in zip(regions, setup.region_px, strict=True):
        assert np.array_equal(got, warp_to_grid(mask, setup, m_rot, cv2.INTER_NEAREST, cv2.BORDER_CONSTANT))
    ref_valid = cv2.erode(
        warp_to_grid(full, setup, m_rot, cv2.INTER_NEAREST, cv2.BORDER_CONSTANT),
        np.ones((3, 3)),
        iterations=2,
    )
    assert np.array_equal(valid, ref_valid)
    assert 0 < valid.sum() < valid.size


def test_stats_passes_fed_frame_by_frame_equal_frame_stats_and_check_counts() -> None:
    drives = [_frames(2, 150), _frames(3, 40)]  # 150 frames: a full chunk and a partial one
    params = DatabaseParams(quality_sources=4)
    ref = frame_stats([_source(d) for d in drives], [150, 40], params)
    passes = [FrameStatsPass(0, 190, params), FrameStatsPass(150, 190, params)]
    for p, frames in zip(passes, drives, strict=True):
        for f in frames:
            p.add(f)
        p.close()
    got = finish_frame_stats(passes, [150, 40], params)
    assert np.array_equal(got.saliency, ref.saliency) and np.array_equal(got.masks, ref.masks)
    assert np.array_equal(got.good, ref.good)
    assert got.classifier is not None and ref.classifier is not None
    assert np.array_equal(got.classifier.coef, ref.classifier.coef)
    with pytest.raises(BadInputError, match="expected 41"):
        finish_frame_stats(passes, [150, 41], params)


def test_prepare_drives_computes_the_database_stats_in_the_odometry_pass() -> None:
    stacks = [_frames(4, 12), _frames(5, 9)]
    drives = [
        MappingDrive(f"d{k}", CAM, np.arange(len(s), dtype=np.float64), _source(s))
        for k, s in enumerate(stacks)
    ]
    params = replace(MAPPING_FAST, database=DatabaseParams(quality_sources=4), use_loop_closures=False)
    prepared = prepare_drives(drives, params, workers=2)
    ref = frame_stats([d.frames for d in drives], [12, 9], params.database, params.images)
    assert prepared.frame_stats is not None and prepared.frame_stats_params == (
        params.database,
        params.images,
    )
    assert np.array_equal(prepared.frame_stats.saliency, ref.saliency)
    assert np.array_equal(prepared.frame_stats.masks, ref.masks)
    assert np.array_equal(prepared.frame_stats.good, ref.good)


def test_pieces_prepared_apart_and_carried_as_arrays_join_to_the_same_result() -> None:
    stacks = [_frames(6, 14), _frames(7, 11), _frames(8, 9)]
    drives = [
        MappingDrive(f"d{k}", CAM, np.arange(len(s), dtype=np.float64) * 0.1, _source(s))
        for k, s in enumerate(stacks)
    ]
    params = replace(MAPPING_FAST, database=DatabaseParams(quality_sources=4))
    whole = prepare_drives(drives, params, workers=1)
    flats = flat_offsets(drives)
    assert flats == [(0, 34), (14, 34), (25, 34)]
    segments = [
        prepare_segment(d, params, flat, (0, d.n_frames))
        for d, flat in zip(reversed(drives), reversed(flats), strict=True)
    ]
    carried = [
        join_segments(
            d, [PreparedSegment.from_arrays(s.to_arrays(), params.database, params.images, *flat)], params
        )
        for d, s, flat in zip(drives, reversed(segments), flats, strict=True)
    ]
    joined = join_drives(carried, drives, params)
    for a, b in zip(whole.chains, joined.chains, strict=True):
        assert np.array_equal(a.iTj, b.iTj) and np.array_equal(a.sigmas, b.sigmas)
    for name in ("raw_poses", "confidence", "thumbs", "keyframes"):
        for a, b in zip(getattr(whole, name), getattr(joined, name), strict=True):
            assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert whole.closures == joined.closures
    assert whole.frame_stats is not None and joined.frame_stats is not None
    for name in ("saliency", "masks", "good"):
        assert np.array_equal(getattr(whole.frame_stats, name), getattr(joined.frame_stats, name)), name
    with pytest.raises(ValueError, match="one prepared piece per drive"):
        join_drives(carried[:2], drives, params)


def _horizon_offset_all_81(
    hom: np.ndarray, pairs: list[tuple[np.ndarray, np.ndarray]], max_px: float
) -> float | None:
    """The horizon search as first written: every grid value, then the root interval nearest 0."""
    if min(abs(p[1][1] - p[0][1]) for p in pairs[1:]) < 2.0:
        return None
    (n1, n2), (f1, f2) = pairs[1], pairs[2]
    pts = np.stack([n1, f1, n2, f2])

    def gap(delta: float) -> float:
        shifted = pts + np.array([0.0, delta])
        if np.any(shifted @ hom[2, :2] + hom[2, 2] <= 0):
            return math.nan
        f = apply_homography(hom, shifted)
        return float(np.linalg.norm(f[0] - f[1]) - np.linalg.norm(f[2] - f[3]))

    grid = np.linspace(-max_px, max_px, 81)
    vals = np.array([gap(float(g)) for g in grid])
    roots = [i for i in range(80) if np.isfinite(vals[i] + vals[i + 1]) and vals[i] * vals[i + 1] <= 0]
    if not roots:
        return None
    i = min(roots, key=lambda j: abs(grid[j]))
    lo, hi, g_lo = float(grid[i]), float(grid[i + 1]), float(vals[i])
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        g_mid = gap(mid)
        lo, hi, g_lo = (mid, hi, g_lo) if g_lo * g_mid > 0 else (lo, mid, g_lo)
    return 0.5 * (lo + hi)


def test_horizon_search_equals_the_full_grid_search() -> None:
    hom = np.asarray(pinhole_camera().homography())
    rng = np.random.default_rng(7)
    found = 0
    for _ in range(300):
        near, far = rng.uniform([80, 190], [240, 215]), rng.uniform([80, 135], [240, 160])
        move = rng.normal([0.0, 8.0], [1.0, 3.0])
        scale = rng.uniform(0.3, 0.9)  # far content moves less in the image; a pitch error changes how much
        pairs = [(near, near), (near, near + move), (far, far + move * scale)]
        ref = _horizon_offset_all_81(hom, pairs, 40.0)
        assert _horizon_offset(hom, pairs, 40.0) == ref
        found += ref is not None
    assert 30 < found < 270  # both outcomes are exercised


def test_a_build_handed_its_database_pair_scores_scores_none_again_and_picks_the_same_references() -> None:
    """The map's reference thumbnails, gathered drive by drive, are the chosen frames' thumbnails; a second
    solve handed the first's pair scores compares nothing anew and chooses the same frames."""
    stacks = [_frames(9, 40), _frames(10, 30)]
    drives = [
        MappingDrive(f"d{k}", CAM, np.arange(len(s), dtype=np.float64) * 0.1, _source(s))
        for k, s in enumerate(stacks)
    ]
    params = replace(MAPPING_FAST, database=DatabaseParams(quality_sources=4), use_loop_closures=False)
    prepared = prepare_drives(drives, params)
    first = solve_map(prepared, drives, params)
    thumbs = np.concatenate(prepared.thumbs)
    assert first.reference_thumbs is not None and first.holistic_thumbs is not None
    assert np.array_equal(first.reference_thumbs, thumbs[first.topomap.chosen])
    assert first.holistic_ptr is not None and first.holistic_thumbs.shape[0] == first.holistic_ptr[-1]
    assert first.database_scores is not None and first.stats["database_pairs_scored"] > 0
    again = solve_map(prepared, drives, params, database_scores=PairScores(*first.database_scores.arrays()))
    assert (again.stats["database_pairs_scored"], again.stats["database_pairs_reused"]) == (
        0,
        first.stats["database_pairs_scored"] + first.stats["database_pairs_reused"],
    )
    assert np.array_equal(again.topomap.chosen, first.topomap.chosen)
