"""One mapping drive's share of a map build: its visual odometry, thumbnails and frame statistics.

Stage 1 of :mod:`driftmap.core.mapping` is independent per drive, so a build can fan it out: threads of one
process, worker processes of one machine, or job workers on several machines. :func:`prepare_drive` is that
unit of work; :class:`PreparedDrive` is its result, which round-trips exactly through plain arrays
(:meth:`PreparedDrive.to_arrays` / :meth:`PreparedDrive.from_arrays`) so that it can cross a process or be kept
as a blob. Joining the pieces of every drive (:func:`driftmap.core.mapping.join_drives`) gives bit for bit
what one process computing every drive gives.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core import posegraph
from driftmap.core.camera import CameraModel
from driftmap.core.images import preprocess
from driftmap.core.odometry import dead_reckon
from driftmap.core.params import ImageParams, OdometryParams
from driftmap.core.place_database import DatabaseParams, FrameStatsPass

F64 = NDArray[np.float64]
FractionFn = Callable[[float], None]
"""``report(fraction)`` of one drive's frames processed, 0..1."""

_STATS_LISTS = ("sal", "masks", "feats", "sample", "sample_sal")  # FrameStatsPass chunk lists kept


class _Tee:
    """Yields frames to odometry while keeping their place-recognition thumbnails and feeding the
    database's frame statistics (when given), so each frame is decoded once."""

    def __init__(
        self,
        frames: Iterable[NDArray[np.uint8]],
        params: ImageParams,
        stats: FrameStatsPass | None,
        report: tuple[FractionFn, int] | None,
    ) -> None:
        self._frames, self._params, self.stats, self._report = frames, params, stats, report
        self.thumbs: list[NDArray[np.float32]] = []

    def __iter__(self) -> Iterator[NDArray[np.uint8]]:
        for frame in self._frames:
            self.thumbs.append(preprocess(frame, self._params))
            if self.stats is not None:
                self.stats.add(frame)
            if self._report is not None:
                self._report[0](len(self.thumbs) / max(self._report[1], 1))
            yield frame


@dataclass(frozen=True, eq=False)
class PreparedDrive:
    """Stage 1 of one drive.

    Attributes:
        chain: the odometry chain (steps (N-1, 3), sigmas (N-1, 3)) for the pose graph.
        raw_poses: (N, 3) float64 dead-reckoned poses [x_m, y_m, yaw_rad] from the drive's start pose.
        confidence: (N,) float64 odometry confidence of the step into each frame (1 for frame 0).
        thumbs: (N, h, w) float32 patch-normalised place-recognition thumbnails.
        stats: the closed per-drive pass of the database's frame statistics (None when the database is off).
        seconds: wall time of the work, seconds.
    """

    chain: posegraph.OdometryChain
    raw_poses: F64
    confidence: F64
    thumbs: NDArray[np.float32]
    stats: FrameStatsPass | None
    seconds: float

    @property
    def n_frames(self) -> int:
        """Frames N of the drive."""
        return int(self.raw_poses.shape[0])

    def to_arrays(self) -> dict[str, NDArray]:
        """Every field as named arrays (for ``np.savez``); :meth:`from_arrays` restores them exactly."""
        out: dict[str, NDArray] = {
            "iTj": self.chain.iTj,
            "sigmas": self.chain.sigmas,
            "raw_poses": self.raw_poses,
            "confidence": self.confidence,
            "thumbs": self.thumbs,
            "seconds": np.array(self.seconds),
        }
        if self.stats is not None:
            for name in _STATS_LISTS:
                chunks = getattr(self.stats, name)
                if chunks:  # one array: concatenating chunks is exact, as finish_frame_stats does
                    out[f"stats_{name}"] = np.concatenate(chunks)
        return out

    @classmethod
    def from_arrays(
        cls,
        arrays: dict[str, NDArray],
        database: DatabaseParams,
        images: ImageParams,
        offset: int,
        total: int,
    ) -> PreparedDrive:
        """The piece stored by :meth:`to_arrays`; ``database``, ``images``, ``offset`` and ``total`` as given
        to :func:`prepare_drive` (they rebuild the statistics pass; ``database.enabled`` off: none)."""
        n = int(arrays["raw_poses"].shape[0])
        stats = None
        if database.enabled:
            stats = FrameStatsPass(offset, total, database, images)
            for name in _STATS_LISTS:
                key = f"stats_{name}"
                setattr(stats, name, [np.asarray(arrays[key])] if key in arrays else [])
            stats.frames, stats.seen = n, offset + n
        chain = posegraph.OdometryChain(np.asarray(arrays["iTj"]), np.asarray(arrays["sigmas"]))
        return cls(
            chain,
            np.asarray(arrays["raw_poses"], dtype=np.float64),
            np.asarray(arrays["confidence"], dtype=np.float64),
            np.asarray(arrays["thumbs"], dtype=np.float32),
            stats,
            float(arrays["seconds"]),
        )


def prepare_drive(
    name: str,
    frames: Iterable[NDArray[np.uint8]],
    n_frames: int,
    camera: CameraModel,
    odometry: OdometryParams,
    images: ImageParams,
    *,
    start_wT: tuple[float, float, float] = (0.0, 0.0, 0.0),
    stats: FrameStatsPass | None = None,
    report: FractionFn | None = None,
) -> PreparedDrive:
    """Stage 1 of one drive: dead reckoning, thumbnails and (when ``stats`` is given) frame statistics.

    Args:
        name: the drive's name (for errors).
        frames: its N gray (H, W) uint8 frames in time order.
        n_frames: N, checked against the frames given.
        camera: its calibrated camera.
        odometry: visual-odometry parameters.
        images: place-recognition pre-processing of the thumbnails.
        start_wT: pose (x_m, y_m, yaw_rad) of the first frame.
        stats: a fresh :class:`FrameStatsPass` of this drive (offset and total of the whole build); closed here.
        report: called with the fraction of frames processed.

    Raises:
        ValueError: the drive gave another number of frames than ``n_frames``.
    """
    start = time.perf_counter()
    tee = _Tee(frames, images, stats, (report, n_frames) if report is not None else None)
    reckoning = dead_reckon(tee, camera, odometry, start_wT)
    if len(tee.thumbs) != n_frames:
        raise ValueError(f"drive {name!r}: {len(tee.thumbs)} frames, but {n_frames} times")
    if stats is not None:
        stats.close()
    steps = reckoning.steps
    iTj = np.array([s.prev_T_curr for s in steps], dtype=np.float64).reshape(-1, 3)
    sigmas = np.array([[s.sigma_xy_m, s.sigma_xy_m, s.sigma_theta_rad] for s in steps]).reshape(-1, 3)
    confidence = np.concatenate([[1.0], [s.confidence for s in steps]])
    return PreparedDrive(
        posegraph.OdometryChain(iTj, sigmas),
        reckoning.wTi,
        confidence,
        np.stack(tee.thumbs),
        stats,
        time.perf_counter() - start,
    )
