"""Read-side views of stored map versions for the API: counts, pose pages, closures, nodes, comparisons."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session, aliased

from driftmap.errors import BadInputError
from driftmap.services.maps import load_topomap
from driftmap.store.blobs import BlobStore
from driftmap.store.models import (
    Drive,
    Frame,
    MapGroundingResidual,
    MapLoopClosure,
    MapNode,
    MapPose,
    MapVersion,
)


def list_versions(session: Session, site_id: int, offset: int, limit: int) -> tuple[list[MapVersion], int]:
    """A site's map versions, newest first, and their number."""
    total = session.scalar(select(func.count()).where(MapVersion.site_id == site_id)) or 0
    rows = session.scalars(
        select(MapVersion)
        .where(MapVersion.site_id == site_id)
        .order_by(MapVersion.version.desc())
        .offset(offset)
        .limit(limit)
    )
    return list(rows), total


def version_counts(session: Session, version: MapVersion) -> dict[str, Any]:
    """Row counts of a version and its residual figures (metres)."""

    def count(model: Any, *where: Any) -> int:
        return (
            session.scalar(
                select(func.count()).select_from(model).where(model.map_version_id == version.id, *where)
            )
            or 0
        )

    mean, top = session.execute(
        select(func.avg(MapGroundingResidual.distance_m), func.max(MapGroundingResidual.distance_m)).where(
            MapGroundingResidual.map_version_id == version.id
        )
    ).one()
    return {
        "poses": count(MapPose),
        "closures": count(MapLoopClosure),
        "closures_accepted": count(MapLoopClosure, MapLoopClosure.accepted.is_(True)),
        "nodes": count(MapNode),
        "residuals": count(MapGroundingResidual),
        "residual_mean_m": float(mean) if mean is not None else None,
        "residual_max_m": float(top) if top is not None else None,
    }


def pose_arrays(session: Session, version: MapVersion, offset: int, limit: int) -> dict[str, Any]:
    """A page of the version's poses as parallel arrays, drive then frame order."""
    total = session.scalar(select(func.count()).where(MapPose.map_version_id == version.id)) or 0
    rows = session.execute(
        select(Frame.drive_id, Frame.index, MapPose.x_m, MapPose.y_m, MapPose.yaw_rad)
        .join(Frame, MapPose.frame_id == Frame.id)
        .where(MapPose.map_version_id == version.id)
        .order_by(Frame.drive_id, Frame.index)
        .offset(offset)
        .limit(limit)
    ).all()
    keys = ("drive_id", "frame", "x_m", "y_m", "yaw_rad")
    page: dict[str, Any] = {"total": total, "offset": offset, "limit": limit}
    for k, key in enumerate(keys):
        page[key] = [row[k] for row in rows]
    return page


def closure_rows(session: Session, version: MapVersion) -> list[dict[str, Any]]:
    """Every loop closure of the version with both frames named by drive id and frame number."""
    frame_a, frame_b = aliased(Frame), aliased(Frame)
    rows = session.execute(
        select(
            frame_a.drive_id,
            frame_a.index,
            frame_b.drive_id,
            frame_b.index,
            MapLoopClosure.d_score,
            MapLoopClosure.accepted,
            MapLoopClosure.chi2,
        )
        .join(frame_a, MapLoopClosure.frame_a_id == frame_a.id)
        .join(frame_b, MapLoopClosure.frame_b_id == frame_b.id)
        .where(MapLoopClosure.map_version_id == version.id)
        .order_by(MapLoopClosure.id)
    ).all()
    keys = ("drive_a", "frame_a", "drive_b", "frame_b", "d_score", "accepted", "chi2")
    return [dict(zip(keys, row, strict=True)) for row in rows]


def node_arrays(session: Session, blobs: BlobStore, version: MapVersion) -> dict[str, Any]:
    """Node centres and the edges of the topological map."""
    rows = session.execute(
        select(MapNode.node, MapNode.x_m, MapNode.y_m)
        .where(MapNode.map_version_id == version.id)
        .order_by(MapNode.node)
    ).all()
    edges = load_topomap(blobs, version).edges
    return {
        "node": [r[0] for r in rows],
        "x_m": [r[1] for r in rows],
        "y_m": [r[2] for r in rows],
        "edges": [(int(a), int(b)) for a, b in np.asarray(edges).reshape(-1, 2)],
    }


@dataclass(frozen=True)
class _Poses:
    frame_ids: np.ndarray
    xy: np.ndarray
    drive_ids: np.ndarray


def _poses(session: Session, version: MapVersion) -> _Poses:
    rows = session.execute(
        select(MapPose.frame_id, MapPose.x_m, MapPose.y_m, Frame.drive_id)
        .join(Frame, MapPose.frame_id == Frame.id)
        .where(MapPose.map_version_id == version.id)
        .order_by(MapPose.frame_id)
    ).all()
    array = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return _Poses(array[:, 0].astype(np.int64), array[:, 1:3], array[:, 3].astype(np.int64))


def compare_versions(session: Session, a: MapVersion, b: MapVersion) -> dict[str, Any]:
    """Per-frame displacement between two versions of one site's map (frames present in both), metres."""
    if a.site_id != b.site_id:
        raise BadInputError("the two map versions belong to different sites", field="b")
    pa, pb = _poses(session, a), _poses(session, b)
    common, ia, ib = np.intersect1d(pa.frame_ids, pb.frame_ids, assume_unique=True, return_indices=True)
    moved = np.linalg.norm(pa.xy[ia] - pb.xy[ib], axis=1) if common.size else np.zeros(0)
    drives = pa.drive_ids[ia]
    names = dict(session.execute(select(Drive.id, Drive.name).where(Drive.site_id == a.site_id)).all())
    per_drive = [
        {
            "drive_id": int(d),
            "drive": names.get(int(d), str(d)),
            "frames": int((drives == d).sum()),
            "mean_m": float(moved[drives == d].mean()),
            "max_m": float(moved[drives == d].max()),
        }
        for d in np.unique(drives)
    ]

    def stat(value: float) -> float | None:
        return float(value) if common.size else None

    return {
        "version_a": a.version,
        "version_b": b.version,
        "frames": int(common.size),
        "only_in_a": int(pa.frame_ids.size - common.size),
        "only_in_b": int(pb.frame_ids.size - common.size),
        "mean_m": stat(moved.mean()) if common.size else None,
        "median_m": stat(np.median(moved)) if common.size else None,
        "p95_m": stat(np.percentile(moved, 95)) if common.size else None,
        "max_m": stat(moved.max()) if common.size else None,
        "per_drive": per_drive,
    }
