"""Map versions: build a site's map from its stored drives and keep it as an immutable version."""

from __future__ import annotations

import dataclasses
import io
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, insert, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from driftmap.core.mapping.pipeline import (
    MAPPING_PAPER,
    MapBuild,
    MappingDrive,
    MappingParams,
    join_drives,
)
from driftmap.core.mapping.prepare import loop_inputs
from driftmap.core.topomap.model import TopoMap
from driftmap.core.types import ProgressFn
from driftmap.errors import ConflictError, NotFoundError
from driftmap.formats.csv_exports import PoseRow
from driftmap.services import jobs as job_service
from driftmap.services import kept_work, loop_searches, map_pieces
from driftmap.services.jobs import Enqueue
from driftmap.services.map_drives import load_mapping_drive, mapping_drives, prepare_site_drives
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.job_models import Job
from driftmap.store.models import (
    Drive,
    Frame,
    Grounding,
    MapGroundingResidual,
    MapLoopClosure,
    MapNode,
    MapNodeFrame,
    MapPose,
    MapVersion,
    Site,
)
from driftmap.store.queries import latest_map_version

LOCALISER_DB_KEY = "localiser_db_sha256"
"""``MapVersion.stats`` key of the localisation database blob: an ``.npz`` of ``thumbs`` (S, h, w) float16
reference thumbnails of every node's chosen frames, node by node, and ``node_ptr`` (M + 1,) int64 offsets;
with the SESAME database on, also ``holistic_thumbs``/``holistic_node_ptr``: [SSLAM]'s plain selection."""


@dataclass(frozen=True, eq=False)
class SiteDrives:
    """A site's mapping drives loaded for the pipeline, with the row ids to store results against."""

    drives: list[Drive]
    inputs: list[MappingDrive]
    frame_ids: list[NDArray[np.int64]]
    """Per drive, (N,) ``frames.id`` in frame order."""
    grounding_ids: list[list[int]]
    """Per drive, ``groundings.id`` in the order of that drive's ``MappingDrive.groundings``."""
    truth: list[NDArray[np.float64] | None]
    """Per drive, (N, 3) ground truth [x_m, y_m, yaw_rad] when every frame has it, else None."""
    contents: list[str]
    """Per drive, what its stage 1 reads, hashed (:func:`driftmap.services.map_pieces.drive_content`)."""


def load_site_drives(session: Session, blobs: BlobStore, site: Site) -> SiteDrives:
    """The mapping drives of ``site`` with their groundings, frames streamed from the blob store."""
    out = SiteDrives([], [], [], [], [], [])
    for drive in mapping_drives(session, site):
        one = load_mapping_drive(session, blobs, drive)
        out.drives.append(drive)
        out.inputs.append(one.input)
        out.frame_ids.append(one.frame_ids)
        out.grounding_ids.append(one.grounding_ids)
        out.truth.append(one.truth)
        out.contents.append(one.content_sha256)
    return out


def _params_json(params: MappingParams) -> dict[str, Any]:
    encoded: dict[str, Any] = json_safe(dataclasses.asdict(params))
    return encoded


def json_safe(value: Any) -> Any:
    """``value`` with tuples as lists and numpy scalars as Python numbers, for JSON columns."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def store_map_version(
    session: Session,
    batch: BlobBatch,
    site: Site,
    loaded: SiteDrives,
    build: MapBuild,
    params: MappingParams,
    created_by: str = "cli",
) -> MapVersion:
    """Write ``build`` as the next immutable map version of ``site``."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **build.topomap.to_arrays())  # type: ignore[arg-type]
    previous = latest_map_version(session, site.id)
    latest = previous.version if previous is not None else 0
    stats = json_safe(build.stats)
    if build.reference_thumbs is not None:
        database = io.BytesIO()
        thumbs = build.reference_thumbs.astype(np.float16)
        arrays = {"thumbs": thumbs, "node_ptr": build.topomap.chosen_ptr.astype(np.int64)}
        if build.holistic_thumbs is not None and build.holistic_ptr is not None:
            arrays["holistic_thumbs"] = build.holistic_thumbs.astype(np.float16)
            arrays["holistic_node_ptr"] = build.holistic_ptr.astype(np.int64)
        np.savez(database, **arrays)  # type: ignore[arg-type]
        stats[LOCALISER_DB_KEY] = batch.put(database.getvalue())
    version = MapVersion(
        site_id=site.id,
        version=latest + 1,
        params=_params_json(params),
        stats=stats,
        topomap_sha256=batch.put(buffer.getvalue()),
        created_by=created_by,
    )
    session.add(version)
    session.flush()
    vid = version.id
    pose_rows = [
        {
            "map_version_id": vid,
            "frame_id": int(fid),
            "x_m": float(p[0]),
            "y_m": float(p[1]),
            "yaw_rad": float(p[2]),
        }
        for ids, poses in zip(loaded.frame_ids, build.wTi, strict=True)
        for fid, p in zip(ids, poses, strict=True)
    ]
    session.execute(insert(MapPose), pose_rows)
    if build.closures:
        session.execute(
            insert(MapLoopClosure),
            [
                {
                    "map_version_id": vid,
                    "frame_a_id": int(loaded.frame_ids[c.drive_a][c.frame_a]),
                    "frame_b_id": int(loaded.frame_ids[c.drive_b][c.frame_b]),
                    "d_score": c.d_score,
                    "accepted": c.accepted,
                    "chi2": c.chi2,
                }
                for c in build.closures
            ],
        )
    grounding_ids = [gid for ids in loaded.grounding_ids for gid in ids]
    if build.residuals:
        session.execute(
            insert(MapGroundingResidual),
            [
                {
                    "map_version_id": vid,
                    "grounding_id": gid,
                    "frame_id": int(loaded.frame_ids[r.drive][r.frame]),
                    "surveyed_x_m": r.surveyed_xy_m[0],
                    "surveyed_y_m": r.surveyed_xy_m[1],
                    "dx_m": r.dx_m,
                    "dy_m": r.dy_m,
                    "distance_m": r.distance_m,
                }
                for gid, r in zip(grounding_ids, build.residuals, strict=True)
            ],
        )
    topo = build.topomap
    all_ids = np.concatenate(loaded.frame_ids)
    session.execute(
        insert(MapNode),
        [
            {"map_version_id": vid, "node": n, "x_m": float(c[0]), "y_m": float(c[1])}
            for n, c in enumerate(topo.centres_m)
        ],
    )
    node_frames = [
        {"map_version_id": vid, "node": n, "frame_id": int(all_ids[flat]), "rank": rank}
        for n in range(topo.n_nodes)
        for rank, flat in enumerate(topo.chosen[topo.chosen_ptr[n] : topo.chosen_ptr[n + 1]])
    ]
    if node_frames:
        session.execute(insert(MapNodeFrame), node_frames)
    session.flush()
    return version


def build_site_map(
    session: Session,
    blobs: BlobStore,
    batch: BlobBatch,
    site: Site,
    params: MappingParams = MAPPING_PAPER,
    progress: ProgressFn | None = None,
    created_by: str = "cli",
    workers: int = 1,
    *,
    full: bool = False,
    stale: set[str] | None = None,
) -> tuple[MapVersion, MapBuild]:
    """Run the mapping pipeline on ``site``'s stored drives and store the result as a new version.

    Segments whose stage-1 piece an earlier build kept are loaded, the rest prepared (with ``workers`` > 1 in
    that many worker processes that open the same database and blob store) and kept (bit-identical either
    way). The loop-closure search resumes the site's kept search over the drives it shares
    (:mod:`driftmap.services.loop_searches`: in its basis and thresholds) and is kept. ``full`` prepares every
    segment again and searches afresh. The SESAME database looks up the pair scores the site's last build
    kept (:mod:`driftmap.services.database_scores`; not with ``full``) and keeps its own. The pose graph is
    solved afresh (:func:`~driftmap.core.mapping.pipeline.solve_map`), so the version equals a full build's.
    ``stale``, when given, receives the blobs of the
    pieces, search and scores this build dropped:
    :func:`driftmap.services.map_pieces.drop_stale` them once committed.
    """
    loaded = load_site_drives(session, blobs, site)
    start = time.perf_counter()
    url = session.get_bind().engine.url.render_as_string(hide_password=False)
    ids = [d.id for d in loaded.drives]
    stage = prepare_site_drives(
        (url, blobs.root),
        batch,
        list(zip(ids, loaded.contents, loaded.inputs, strict=True)),
        params,
        (lambda _keys: {}) if full else (lambda keys: map_pieces.kept_pieces(session, blobs, keys)),
        workers,
        progress,
    )
    odometry_s = time.perf_counter() - start
    keys = [key for _d, _s, key, _sha in stage.segments]
    chains = loop_searches.chain_keys(keys, loaded.inputs, params)
    loops, plan, scored = None, None, []
    if params.use_loop_closures:
        start = time.perf_counter()
        _keyframes, thumbs, times = loop_inputs(stage.pieces, loaded.inputs, params)
        plan = loop_searches.plan_loops(session, blobs, batch, site.id, (chains, thumbs, times), params, full)
        scored = [] if plan is None else loop_searches.score_here(plan, params, batch, progress)
        found = () if plan is None else tuple(loop_searches.decide(plan, params, scored).closures)
        loops = (found, time.perf_counter() - start)
    prepared = join_drives(stage.pieces, loaded.inputs, params, progress, odometry_s, loops)
    search = None if plan is None else (plan, scored)
    kept = kept_work.KeptWork(chains, ids, stage.segments, stage.reused, search)
    build, dropped = kept_work.solve_and_keep(
        session, blobs, batch, site, loaded.inputs, prepared, params, kept, progress, full
    )
    if stale is not None:
        stale |= dropped
    return store_map_version(session, batch, site, loaded, build, params, created_by), build


def get_map_version(session: Session, site: Site, version: int | None = None) -> MapVersion:
    """Version ``version`` of ``site``'s map, or the latest when None."""
    if version is None:
        found = latest_map_version(session, site.id)
    else:
        query = select(MapVersion).where(MapVersion.site_id == site.id, MapVersion.version == version)
        found = session.scalars(query.limit(1)).first()
    if found is None:
        what = f"version {version}" if version is not None else "map version yet"
        raise NotFoundError(f"site {site.name!r} has no {what}; run `driftmap map build {site.name}`")
    return found


def load_topomap(blobs: BlobStore, version: MapVersion) -> TopoMap:
    """The topological map of a stored version."""
    with np.load(io.BytesIO(blobs.get(version.topomap_sha256))) as arrays:
        return TopoMap.from_arrays({k: arrays[k] for k in arrays.files})


def pose_rows(session: Session, version: MapVersion) -> list[PoseRow]:
    """The poses CSV rows of a version: every frame of every mapping drive, drive then frame order."""
    query = (
        select(Drive.name, Frame.index, MapPose.x_m, MapPose.y_m, MapPose.yaw_rad)
        .join(Frame, MapPose.frame_id == Frame.id)
        .join(Drive, Frame.drive_id == Drive.id)
        .where(MapPose.map_version_id == version.id)
        .order_by(Drive.id, Frame.index)
    )
    return [
        PoseRow(drive=d, frame=i, x_m=x, y_m=y, yaw_rad=yaw)
        for d, i, x, y, yaw in session.execute(query).all()
    ]


def ensure_buildable(session: Session, site: Site) -> None:
    """Refuse a build for a site with a mapping drive without frames (nothing to map: name it and delete it
    or post its frames), or with no enabled grounding on a mapping drive (the map could not be placed).

    Raises:
        ConflictError: either case, naming the empty drives.
    """
    empty = session.scalars(
        select(Drive.name)
        .where(
            Drive.site_id == site.id,
            Drive.kind == "mapping",
            ~select(Frame.id).where(Frame.drive_id == Drive.id).exists(),
        )
        .order_by(Drive.id)
    ).all()
    if empty:
        names = ", ".join(repr(n) for n in empty)
        raise ConflictError(
            f"site {site.name!r} has mapping drives without frames: {names}; add their frames or delete them"
        )
    grounded = session.scalar(
        select(func.count())
        .select_from(Grounding)
        .join(Drive)
        .where(Drive.site_id == site.id, Drive.kind == "mapping", Grounding.enabled.is_(True))
    )
    if not grounded:
        raise ConflictError(
            f"site {site.name!r} has no grounding on any mapping drive that is enabled; "
            "ground (or enable) at least two frames first"
        )


def submit_build(
    session: Session, enqueue: Enqueue, site: Site, args: dict[str, Any], created_by: str
) -> Job:
    """Queue a ``map.build`` job of ``site`` (see :func:`driftmap.services.jobs.submit`).

    Raises:
        BadInputError: the site cannot be built (:func:`ensure_buildable`).
        ConflictError: a build of the site is already queued or running, naming its job; of two requests
            that race, the jobs table's one-unfinished-build-per-site index refuses the second (the session
            must then be rolled back).
    """
    ensure_buildable(session, site)
    busy = session.scalar(
        select(Job)
        .where(
            Job.kind == "map.build",
            Job.site_id == site.id,
            Job.parent_id.is_(None),
            Job.status.in_(("queued", "running")),
        )
        .order_by(Job.id)
        .limit(1)
    )
    refusal = f"site {site.name!r} is already building its map"
    advice = "wait for it to end or cancel it"
    if busy is not None:
        raise ConflictError(f"{refusal} (job {busy.id}, {busy.status}); {advice}")
    try:
        return job_service.submit(session, enqueue, "map.build", args, site_id=site.id, created_by=created_by)
    except IntegrityError:  # the session's transaction is spoilt: the caller rolls it back
        raise ConflictError(f"{refusal} (a build was queued at the same moment); {advice}") from None
