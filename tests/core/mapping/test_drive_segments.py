"""Stage 1 of a map build in drive segments: the spans, and segments prepared apart (in any order, carried
as arrays) joining to exactly what one pass over the whole drive gives."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from driftmap.core.imaging.images import preprocess
from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.views import thumbnails, undistorted_view
from driftmap.core.mapping.drive import PreparedSegment
from driftmap.core.mapping.pipeline import (
    MAPPING_PAPER,
    MappingDrive,
    MappingParams,
    drive_segments,
    join_segments,
    prepare_segment,
    restride_segment,
)
from driftmap.core.odometry.drive import dead_reckon
from driftmap.core.topomap.database import DATABASE_OFF, STATS_CHUNK, DatabaseParams, FrameStatsPass
from tests.core.odometry.test_drive import arc_step, floor_texture, pinhole_camera, render

START = (0.0, -2.0, 0.0)
N_FRAMES = 300  # three segments of at most 128 frames
LENS_FRAMES = 20  # frames of the segment seen through a lens
FISHEYE = Lens(
    "fisheye", ((250.0, 0.0, 160.0), (0.0, 250.0, 120.0), (0.0, 0.0, 1.0)), (0.05, -0.02, 0.0, 0.0)
)


@pytest.mark.parametrize(
    ("n", "most", "spans"),
    [
        (
            3282,
            512,
            [(0, 512), (512, 1024), (1024, 1536), (1536, 2048), (2048, 2560), (2560, 3072), (3072, 3282)],
        ),
        (1833, 1024, [(0, 1024), (1024, 1833)]),
        (2011, 1024, [(0, 1024), (1024, 2011)]),
        (300, 128, [(0, 128), (128, 256), (256, 300)]),
        (100, 512, [(0, 100)]),
        (0, 512, [(0, 0)]),
    ],
)
def test_spans_cover_the_drive_in_chunk_aligned_segments(
    n: int, most: int, spans: list[tuple[int, int]]
) -> None:
    got = drive_segments(n, most)
    assert got == spans
    assert all(a % STATS_CHUNK == 0 and b - a <= most for a, b in got)


def test_segment_length_must_be_a_multiple_of_the_statistics_chunk() -> None:
    with pytest.raises(ValueError, match="multiple of 128"):
        MappingParams(segment_frames=200)


@pytest.fixture(scope="module")
def circle() -> np.ndarray:
    """A vehicle driving a slow circle of 2.5 m radius over gravel, with a short stop."""
    cam, tex = pinhole_camera(), floor_texture()
    poses = [START]
    for k in range(N_FRAMES - 1):
        d = 0.0 if 140 <= k < 150 else 0.05 + 0.01 * math.sin(k / 7)
        poses.append(arc_step(poses[-1], d, d / 2.5, cam.y_c_m))
    return np.stack([render(tex, cam, p) for p in poses])


def test_segments_prepared_apart_join_to_the_whole_drive(circle: np.ndarray) -> None:
    cam = pinhole_camera()
    drive = MappingDrive(
        "circle", cam, np.arange(N_FRAMES) * 0.1, lambda: iter(circle), start_wT=START,
        frame_range=lambda begin, stop: iter(circle[begin:stop]),
    )  # fmt: skip
    params = replace(MAPPING_PAPER, segment_frames=128, database=DatabaseParams(quality_sources=4))
    flat = (40, N_FRAMES + 40)  # as if a 40-frame drive came first
    spans = drive_segments(N_FRAMES, params.segment_frames)
    pieces = {
        span: PreparedSegment.from_arrays(
            prepare_segment(drive, params, flat, span).to_arrays(),
            params.database,
            params.images,
            flat[0] + span[0],
            flat[1],
        )
        for span in reversed(spans)
    }
    joined = join_segments(drive, [pieces[s] for s in spans], params)

    whole = dead_reckon(circle, cam, params.odometry, START)
    np.testing.assert_array_equal(joined.raw_poses, whole.wTi)
    np.testing.assert_array_equal(joined.chain.iTj, np.array([s.prev_T_curr for s in whole.steps]))
    assert joined.confidence.tolist() == [1.0] + [s.confidence for s in whole.steps]
    np.testing.assert_array_equal(joined.thumbs, np.stack([preprocess(f, params.images) for f in circle]))
    one_pass = FrameStatsPass(*flat, params.database, params.images)
    for frame in circle:
        one_pass.add(frame)
    one_pass.close()
    assert joined.stats is not None and (joined.stats.frames, joined.stats.seen) == (N_FRAMES, flat[1])
    for name in ("sal", "masks", "feats", "sample", "sample_sal"):
        np.testing.assert_array_equal(
            np.concatenate(getattr(joined.stats, name)), np.concatenate(getattr(one_pass, name)), name
        )
    travelled = np.linalg.norm(np.diff(joined.raw_poses[:, :2], axis=0), axis=1)
    assert np.all(travelled[140:150] == 0.0)  # the stop, inside the second segment, read as stationary


def test_segments_that_leave_a_gap_are_refused(circle: np.ndarray) -> None:
    cam = pinhole_camera()
    drive = MappingDrive("circle", cam, np.arange(N_FRAMES) * 0.1, lambda: iter(circle), start_wT=START)
    params = replace(MAPPING_PAPER, segment_frames=128, database=DATABASE_OFF)
    first, last = (prepare_segment(drive, params, (0, N_FRAMES), span) for span in [(0, 128), (256, 300)])
    with pytest.raises(ValueError, match="do not cover its 300 frames"):
        join_segments(drive, [first, last], params)
    with pytest.raises(ValueError, match=r"frames 256\.\.299 asked for, 0 given"):
        prepare_segment(replace(drive, frame_range=lambda b, s: iter(())), params, (0, N_FRAMES), (256, 300))


def test_a_lens_camera_gives_thumbnails_and_statistics_of_its_view(circle: np.ndarray) -> None:
    cam = replace(pinhole_camera(), lens=FISHEYE)
    frames = circle[:LENS_FRAMES]
    drive = MappingDrive("lens", cam, np.arange(LENS_FRAMES) * 0.1, lambda: iter(frames), start_wT=START)
    params = replace(MAPPING_PAPER, database=DatabaseParams(quality_sources=4))
    piece = prepare_segment(drive, params, (0, LENS_FRAMES), (0, LENS_FRAMES))
    np.testing.assert_array_equal(piece.thumbs, thumbnails(frames, params.images, FISHEYE))
    assert not np.array_equal(piece.thumbs, preprocess(frames, params.images))
    one_pass = FrameStatsPass(0, LENS_FRAMES, params.database, params.images)
    for frame in frames:
        one_pass.add(undistorted_view(frame, FISHEYE))
    one_pass.close()
    assert piece.stats is not None
    np.testing.assert_array_equal(np.concatenate(piece.stats.masks), np.concatenate(one_pass.masks))


@pytest.mark.parametrize("flat", [(0, N_FRAMES), (40, N_FRAMES + 40), (97, 3 * N_FRAMES)])
def test_a_kept_segment_restrided_for_another_build_is_what_that_build_prepares(
    circle: np.ndarray, flat: tuple[int, int]
) -> None:
    drive = MappingDrive(
        "circle", pinhole_camera(), np.arange(N_FRAMES) * 0.1, lambda: iter(circle),
        frame_range=lambda begin, stop: iter(circle[begin:stop]),
    )  # fmt: skip
    params = replace(MAPPING_PAPER, segment_frames=128, database=DatabaseParams(quality_sources=4))
    span = (128, 256)
    kept = prepare_segment(drive, params, (0, N_FRAMES), span).to_arrays()  # prepared alone, kept
    sampled = (int(kept["stats_first"]), int(kept["stats_stride"]))
    loaded = PreparedSegment.from_arrays(kept, params.database, params.images, flat[0] + span[0], flat[1])
    again = restride_segment(loaded, drive, params, sampled)
    fresh = prepare_segment(drive, params, flat, span)
    assert again.stats is not None and fresh.stats is not None
    for name in ("sal", "masks", "feats", "sample", "sample_sal"):
        np.testing.assert_array_equal(
            np.concatenate(getattr(again.stats, name)), np.concatenate(getattr(fresh.stats, name)), name
        )
    assert (again.stats.seen, again.stats.frames, again.stats.stride) == (
        fresh.stats.seen,
        fresh.stats.frames,
        fresh.stats.stride,
    )
