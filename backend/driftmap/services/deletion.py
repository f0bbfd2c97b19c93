"""Deleting sites, drives and map versions with their rows, then the blobs nothing refers to any more.

Rows go inside the caller's transaction (foreign keys cascade in the database); the blobs they referred to
are returned as candidates (for a drive and a site also their kept map-build pieces; for a site also those
its jobs name in their args and results, keys ending in ``_sha256``: uploads waiting for import, odometry
pieces and loop-closure blocks of failed builds, localisation CSVs), and :func:`delete_unreferenced_blobs` removes those still unreferenced once the
caller has committed, so a rolled-back delete never loses a blob.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from driftmap.errors import ConflictError
from driftmap.services import database_scores, loop_searches
from driftmap.services.localisation import LOCALISER_DB_KEY
from driftmap.store.blobs import BlobStore
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, Frame, MapPiece, MapPose, MapVersion, Site, SurveyMap
from driftmap.store.storage import Storage

UNFINISHED = ("queued", "running")


def _version_blobs(version: MapVersion) -> set[str]:
    shas = {version.topomap_sha256}
    extra = (version.stats or {}).get(LOCALISER_DB_KEY)
    if isinstance(extra, str):
        shas.add(extra)
    return shas


def _named_blobs(rows: Iterable[tuple[dict[str, Any] | None, dict[str, Any] | None]]) -> set[str]:
    """The blobs named by jobs' ``(args, result)``: string values of keys ending in ``_sha256``."""
    return {
        value
        for args, result in rows
        for values in (args or {}, result or {})
        for key, value in values.items()
        if key.endswith("_sha256") and isinstance(value, str)
    }


def delete_map_version(session: Session, version: MapVersion) -> set[str]:
    """Delete one map version (poses, closures, residuals, nodes cascade); returns candidate blobs."""
    candidates = _version_blobs(version)
    session.execute(delete(MapVersion).where(MapVersion.id == version.id))
    return candidates


def delete_drive(session: Session, drive: Drive) -> set[str]:
    """Delete a drive with its frames and groundings; returns its frame blobs as candidates.

    Raises:
        ConflictError: a map version holds poses of the drive (delete those versions first).
    """
    versions = session.scalars(
        select(MapVersion.version)
        .distinct()
        .join(MapPose, MapPose.map_version_id == MapVersion.id)
        .join(Frame, MapPose.frame_id == Frame.id)
        .where(Frame.drive_id == drive.id)
        .order_by(MapVersion.version)
    ).all()
    if versions:
        listed = ", ".join(str(v) for v in versions)
        raise ConflictError(f"drive {drive.name!r} is part of map version(s) {listed}; delete those first")
    candidates = set(session.scalars(select(Frame.blob_sha256).distinct().where(Frame.drive_id == drive.id)))
    candidates |= set(session.scalars(select(MapPiece.blob_sha256).where(MapPiece.drive_id == drive.id)))
    session.execute(delete(Drive).where(Drive.id == drive.id))
    return candidates


def delete_site(session: Session, site: Site) -> set[str]:
    """Delete a site with everything in it; returns every blob it referred to as candidates."""
    candidates = set(
        session.scalars(
            select(Frame.blob_sha256)
            .distinct()
            .join(Drive, Frame.drive_id == Drive.id)
            .where(Drive.site_id == site.id)
        )
    )
    candidates |= set(session.scalars(select(SurveyMap.dxf_sha256).where(SurveyMap.site_id == site.id)))
    candidates |= set(
        session.scalars(
            select(MapPiece.blob_sha256)
            .join(Drive, MapPiece.drive_id == Drive.id)
            .where(Drive.site_id == site.id)
        )
    )
    candidates |= loop_searches.site_blobs(session, site.id) | database_scores.site_blobs(session, site.id)
    for version in session.scalars(select(MapVersion).where(MapVersion.site_id == site.id)):
        candidates |= _version_blobs(version)
    candidates |= _named_blobs(
        session.execute(select(Job.args, Job.result).where(Job.site_id == site.id)).all()
    )
    session.execute(delete(Site).where(Site.id == site.id))
    return candidates


def referenced(session: Session, shas: Iterable[str]) -> set[str]:
    """Those of ``shas`` that a frame, a survey map, a map version, a kept map piece, loop-closure search or
    database pair scores, or a job still refers to."""
    wanted = set(shas)
    found: set[str] = set()
    items = sorted(wanted)
    for start in range(0, len(items), 500):
        chunk = items[start : start + 500]
        found |= set(session.scalars(select(Frame.blob_sha256).where(Frame.blob_sha256.in_(chunk))))
        found |= set(session.scalars(select(SurveyMap.dxf_sha256).where(SurveyMap.dxf_sha256.in_(chunk))))
        found |= set(
            session.scalars(select(MapVersion.topomap_sha256).where(MapVersion.topomap_sha256.in_(chunk)))
        )
        found |= set(session.scalars(select(MapPiece.blob_sha256).where(MapPiece.blob_sha256.in_(chunk))))
    found |= loop_searches.held_blobs(session, wanted) | database_scores.held_blobs(session, wanted)
    for stats in session.scalars(select(MapVersion.stats)):
        extra = (stats or {}).get(LOCALISER_DB_KEY)
        if extra in wanted:
            found.add(extra)
    finished = select(Job.id).where(Job.status.not_in(UNFINISHED))
    naming = select(Job.args, Job.result).where(  # a finished build's pieces and scores are held by its
        ~(Job.kind.in_(("map.drive", "map.loops")) & Job.parent_id.in_(finished))  # kept ones, if kept
    )
    found |= _named_blobs(session.execute(naming).all()) & wanted
    return found


def delete_unreferenced_blobs(storage: Storage, shas: Iterable[str]) -> int:
    """After the deleting transaction committed: remove the blobs of ``shas`` nothing refers to."""
    candidates = set(shas)
    if not candidates:
        return 0
    with storage.db.session() as session:
        keep = referenced(session, candidates)
    blobs: BlobStore = storage.blobs
    for sha in candidates - keep:
        blobs.delete(sha)
    return len(candidates - keep)
