"""Localisation against a stored map version: load the localiser's map, run recorded frames through it.

The batch CLI (``driftmap localise``), the evaluation report and the live server share these functions:
:func:`load_localiser_map` turns a stored map version into a :class:`~driftmap.core.localisation.map.LocaliserMap`
(reference thumbnails of every node's chosen frames, node centres, sparse adjacency), :func:`make_localiser`
configures a :class:`~driftmap.core.localisation.localiser.Localiser` (SESAME masks and the temporal filter switchable)
and :func:`localise_frames` runs a sequence of frames through it.

Reference thumbnails come from the version's localisation database blob when the build stored one (its
SHA-256 under ``stats["localiser_db_sha256"]``, see :mod:`driftmap.services.maps`); otherwise they are made
again from the stored frames of the version's node frames, with the pre-processing the version was built with,
each through its drive camera's thumbnail view (:mod:`driftmap.core.imaging.views`) as the build made them.
Where each reference frame was taken (its optimised pose in the version) makes the localiser's place fixes
finer than the node centres, and the mapping drives' optimised poses are the paths its continuous track
follows.
"""

from __future__ import annotations

import io
import logging
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.params import IMAGES_DEFAULT, ImageParams
from driftmap.core.imaging.views import thumbnails
from driftmap.core.localisation import hmm
from driftmap.core.localisation.localiser import Estimate, Localiser
from driftmap.core.localisation.map import LocaliserMap, mapped_paths
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.sesame.masks import SESAME_DEFAULT, SesameParams
from driftmap.core.types import F64, I64, ProgressFn
from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import LocalisationRow
from driftmap.formats.drive_json import parse_camera_block
from driftmap.services.drives import frame_rows, stored_frames
from driftmap.services.maps import LOCALISER_DB_KEY, get_map_version, load_topomap
from driftmap.store.blobs import BlobStore
from driftmap.store.models import Drive, Frame, MapNodeFrame, MapPose, MapVersion, Site

__all__ = [
    "LOCALISER_DB_KEY",
    "RecordedDrive",
    "estimate_rows",
    "image_params_of",
    "load_localisation_drives",
    "load_localiser_map",
    "load_version_localiser_map",
    "localise_frames",
    "make_localiser",
    "sesame_params_of",
]

log = logging.getLogger(__name__)

#: a known start further than this from every node is a mistake (wrong site or coordinates), metres
START_MAX_OFF_MAP_M = 50.0


def _tuples(value: Any) -> Any:
    """JSON lists back to tuples (dataclass fields of the params are tuples)."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def image_params_of(version: MapVersion) -> ImageParams:
    """The place-recognition pre-processing a map version was built with (default when not recorded)."""
    stored = (version.params or {}).get("images")
    if not isinstance(stored, dict):
        return IMAGES_DEFAULT
    known = {k: _tuples(v) for k, v in stored.items() if k in ImageParams.__dataclass_fields__}
    return replace(IMAGES_DEFAULT, **known)


def sesame_params_of(version: MapVersion) -> SesameParams:
    """The SESAME mask parameters a map version's database was built with (driftmap's default when none)."""
    stored = ((version.params or {}).get("database") or {}).get("sesame")
    if not isinstance(stored, dict):
        return SESAME_DEFAULT
    known = {k: _tuples(v) for k, v in stored.items() if k in SesameParams.__dataclass_fields__}
    return replace(SESAME_DEFAULT, **known)


def _stored_database(
    blobs: BlobStore, version: MapVersion, holistic: bool
) -> tuple[NDArray[np.float32], NDArray[np.int64]] | None:
    sha = (version.stats or {}).get(LOCALISER_DB_KEY)
    if not isinstance(sha, str) or not blobs.exists(sha):
        return None
    with np.load(io.BytesIO(blobs.get(sha))) as arrays:
        prefix = "holistic_" if holistic and "holistic_thumbs" in arrays.files else ""
        thumbs = np.asarray(arrays[f"{prefix}thumbs"], dtype=np.float32)
        return thumbs, np.asarray(arrays[f"{prefix}node_ptr"], dtype=np.int64)


def _thumbs_from_frames(
    session: Session, blobs: BlobStore, version: MapVersion, n_nodes: int, image_params: ImageParams
) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
    rows = session.execute(
        select(MapNodeFrame.node, Frame.blob_sha256, Frame.drive_id)
        .join(Frame, MapNodeFrame.frame_id == Frame.id)
        .where(MapNodeFrame.map_version_id == version.id)
        .order_by(MapNodeFrame.node, MapNodeFrame.rank)
    ).all()
    lenses = _drive_lenses(session, {int(drive_id) for _n, _s, drive_id in rows})
    h, w = (image_params.size_px or (0, 0))[::-1]
    frames = stored_frames(blobs, [sha for _node, sha, _drive in rows])
    thumbs = [
        thumbnails(frame, image_params, lenses[drive_id])
        for frame, (_node, _sha, drive_id) in zip(frames, rows, strict=True)
    ]
    counts = np.bincount(np.array([r[0] for r in rows], dtype=np.int64), minlength=n_nodes)
    stack = np.stack(thumbs) if thumbs else np.zeros((0, h, w), dtype=np.float32)
    return stack.astype(np.float32), np.r_[0, np.cumsum(counts)].astype(np.int64)


def _drive_lenses(session: Session, drive_ids: set[int]) -> dict[int, Lens | None]:
    """The lens of each drive's camera (None for a camera without one), by drive id."""
    drives = session.execute(select(Drive.id, Drive.name, Drive.camera).where(Drive.id.in_(drive_ids))).all()
    return {int(i): parse_camera_block(camera, "", f"drive {name!r}").lens for i, name, camera in drives}


def _reference_positions(session: Session, version: MapVersion, n_refs: int) -> NDArray[np.float64] | None:
    """(S, 2) float64 the optimised positions (survey metres) of the version's node frames in node and rank
    order, the order of the stored references; None when they do not line up with the ``n_refs`` references."""
    rows = session.execute(
        select(MapPose.x_m, MapPose.y_m)
        .select_from(MapNodeFrame)
        .join(
            MapPose,
            (MapPose.frame_id == MapNodeFrame.frame_id)
            & (MapPose.map_version_id == MapNodeFrame.map_version_id),
        )
        .where(MapNodeFrame.map_version_id == version.id)
        .order_by(MapNodeFrame.node, MapNodeFrame.rank)
    ).all()
    if len(rows) != n_refs:
        log.warning("map version %s: %d reference positions for %d references", version.id, len(rows), n_refs)
        return None
    return np.asarray(rows, dtype=np.float64).reshape(-1, 2)


def _mapped_paths(session: Session, version: MapVersion, max_gap_m: float) -> tuple[F64 | None, I64]:
    """The version's mapped trajectories (:func:`~driftmap.core.localisation.map.mapped_paths`): each mapping
    drive's optimised poses in frame order; (None, empty) when it has no poses."""
    rows = session.execute(
        select(Frame.drive_id, MapPose.x_m, MapPose.y_m)
        .join(Frame, MapPose.frame_id == Frame.id)
        .where(MapPose.map_version_id == version.id)
        .order_by(Frame.drive_id, Frame.index)
    ).all()
    if not rows:
        return None, np.zeros((0, 2), dtype=np.int64)
    drive = np.asarray([r[0] for r in rows], dtype=np.int64)
    chain_ptr = np.r_[0, np.flatnonzero(np.diff(drive)) + 1, drive.size].astype(np.int64)
    xy = np.asarray([(r[1], r[2]) for r in rows], dtype=np.float64)
    return mapped_paths(xy, chain_ptr, max_gap_m=max_gap_m)


def load_version_localiser_map(
    session: Session, blobs: BlobStore, version: MapVersion, *, holistic: bool = False
) -> LocaliserMap:
    """The :class:`LocaliserMap` of one stored map version (see the module docstring for the sources).

    ``holistic`` takes [SSLAM]'s plain reference selection (a few frames per node by heading) instead of
    the SESAME database, when the version holds both; it is what holistic SAD is compared against, and its
    place fixes are the node centres, as in the paper.
    """
    topomap = load_topomap(blobs, version)
    image_params = image_params_of(version)
    stored = _stored_database(blobs, version, holistic)
    if stored is None:
        log.info("map version %s has no localisation database blob; decoding its node frames", version.id)
        stored = _thumbs_from_frames(session, blobs, version, topomap.n_nodes, image_params)
    thumbs, node_ptr = stored
    path_xy_m, path_segments = _mapped_paths(session, version, topomap.params.max_frame_step_m)
    if node_ptr.shape != (topomap.n_nodes + 1,):
        raise BadInputError(
            f"map version {version.version}: database has {node_ptr.size - 1} nodes, map {topomap.n_nodes}",
            field="node_ptr",
        )
    return LocaliserMap(
        thumbs=np.ascontiguousarray(thumbs),
        node_ptr=node_ptr,
        centres_m=np.asarray(topomap.centres_m, dtype=np.float64),
        adjacency_m=topomap.adjacency_m,
        max_adjacency_m=float(topomap.params.max_adjacency_m),
        image_params=image_params,
        edges=np.asarray(topomap.edges, dtype=np.int64).reshape(-1, 2),
        ref_xy_m=None if holistic else _reference_positions(session, version, int(thumbs.shape[0])),
        path_xy_m=path_xy_m,
        path_segments=path_segments,
    )


def load_localiser_map(
    session: Session, blobs: BlobStore, site: Site, version: int | None = None, *, holistic: bool = False
) -> LocaliserMap:
    """The localiser's map of ``site``'s map version ``version`` (latest when None).

    ``holistic``: [SSLAM]'s plain reference frames instead of the SESAME database (see
    :func:`load_version_localiser_map`).

    Raises:
        NotFoundError: the site has no (such) map version.
    """
    return load_version_localiser_map(
        session, blobs, get_map_version(session, site, version), holistic=holistic
    )


def make_localiser(
    lmap: LocaliserMap,
    *,
    sesame: SesameParams | None = SESAME_DEFAULT,
    temporal: bool = True,
    params: hmm.HmmParams = hmm.DEFAULT,
    start_xy_m: tuple[float, float] | None = None,
    start_radius_m: float = 0.0,
    camera: CameraModel | None = None,
    odometry: bool = True,
) -> Localiser:
    """A :class:`Localiser` on ``lmap``: SESAME masks unless ``sesame`` is None, HMM filter unless not temporal.

    ``start_xy_m`` is the vehicle's known start (survey frame, metres): the belief starts at the nearest node
    and the nodes within ``start_radius_m`` of it ([SSLAM]'s X_0), the continuous track at the point; None
    starts it global (uniform). ``camera`` is the vehicle's calibrated camera: its lens undistorts the query
    frames to the view the map's frames of that camera were taken in (:mod:`driftmap.core.imaging.views`),
    and with ``odometry`` its ground-plane odometry moves the belief and the track (None, or ``odometry``
    off: appearance alone).
    """
    start = None
    if start_xy_m is not None:
        start = lmap.nearest_node(*start_xy_m)
        off_m = float(np.hypot(*(lmap.centres_m[start] - np.asarray(start_xy_m))))
        if off_m > START_MAX_OFF_MAP_M:
            raise BadInputError(
                f"the start ({start_xy_m[0]:.1f}, {start_xy_m[1]:.1f}) is {off_m:.0f} m from the map's nearest "
                f"node (at most {START_MAX_OFF_MAP_M:g} m)",
                field="start",
            )
    return Localiser(
        lmap,
        params,
        single_image=not temporal,
        sesame=sesame,
        start_node=start,
        start_radius_m=start_radius_m,
        start_xy_m=start_xy_m,
        camera=camera if odometry else None,
        lens=camera.lens if camera is not None else None,
    )


def localise_frames(
    localiser: Localiser,
    frames: Iterable[NDArray[np.generic]],
    t_s: Sequence[float] | NDArray[np.float64],
    progress: ProgressFn | None = None,
) -> list[Estimate]:
    """Run frames through ``localiser`` in time order, one :class:`Estimate` per frame.

    Args:
        localiser: the localiser; its state carries over from earlier calls.
        frames: (H, W) uint8 grey frames (or colour), as recorded.
        t_s: (N,) frame timestamps, seconds, one per frame.
        progress: called with ("localise", fraction done) now and then.

    Raises:
        BadInputError: fewer or more frames than timestamps.
    """
    times = np.asarray(t_s, dtype=np.float64)
    out: list[Estimate] = []
    n = times.shape[0]
    for k, frame in enumerate(frames):
        if k >= n:
            raise BadInputError(f"more frames than the {n} timestamps", field="frames")
        out.append(localiser.step(frame, float(times[k])))
        if progress is not None and k % 50 == 0:
            progress("localise", k / max(n, 1))
    if len(out) != n:
        raise BadInputError(f"{len(out)} frames for {n} timestamps", field="frames")
    if progress is not None:
        progress("localise", 1.0)
    return out


def estimate_rows(frame_numbers: Sequence[int], estimates: Sequence[Estimate]) -> list[LocalisationRow]:
    """The localisation CSV rows (formats.md) of a run: ``score`` is the reported (calibrated) confidence."""

    def known(value: float) -> float | None:
        return value if np.isfinite(value) else None

    return [
        LocalisationRow(
            int(f),
            e.node,
            e.x_m,
            e.y_m,
            e.confidence,
            e.matched,
            known(e.yaw_rad),
            known(e.speed_mps),
            e.odometry,
            e.score,
        )
        for f, e in zip(frame_numbers, estimates, strict=True)
    ]


@dataclass(frozen=True, eq=False)
class RecordedDrive:
    """A stored localisation drive, frames streamed from the blob store.

    Attributes:
        name: the drive's name.
        frame_numbers: (N,) int64 frame numbers of the drive folder.
        t_s: (N,) float64 timestamps, seconds.
        truth_xy_m: (N, 2) float64 true floor points (survey frame, metres) when every frame has one, else None.
        frames: returns a fresh iterator over the N grey (H, W) uint8 frames in time order.
        camera: the drive's calibrated camera (its odometry runs in the localiser).
    """

    name: str
    frame_numbers: NDArray[np.int64]
    t_s: NDArray[np.float64]
    truth_xy_m: NDArray[np.float64] | None
    frames: Callable[[], Iterator[NDArray[np.uint8]]]
    camera: CameraModel | None = None


def load_localisation_drives(session: Session, blobs: BlobStore, site: Site) -> list[RecordedDrive]:
    """Every stored drive of kind ``localisation`` of ``site``, in import order."""
    drives = session.scalars(
        select(Drive).where(Drive.site_id == site.id, Drive.kind == "localisation").order_by(Drive.id)
    ).all()
    out = []
    for drive in drives:
        rows = frame_rows(session, drive)
        has_truth = bool(rows) and all(f.true_x_m is not None and f.true_y_m is not None for f in rows)
        truth = np.array([[f.true_x_m, f.true_y_m] for f in rows], dtype=np.float64) if has_truth else None
        shas = [f.blob_sha256 for f in rows]

        def frames(shas: list[str] = shas) -> Iterator[NDArray[np.uint8]]:
            return stored_frames(blobs, shas)

        out.append(
            RecordedDrive(
                name=drive.name,
                frame_numbers=np.array([f.index for f in rows], dtype=np.int64),
                t_s=np.array([f.t_s for f in rows], dtype=np.float64),
                truth_xy_m=truth,
                frames=frames,
                camera=parse_camera_block(drive.camera, "", f"drive {drive.name!r}"),
            )
        )
    return out
