"""Queries that several services share, so that each question is asked of the database in one way."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.store.models import MapVersion

__all__ = ["latest_map_version"]


def latest_map_version(session: Session, site_id: int) -> MapVersion | None:
    """The newest map version of a site (highest version number), or None when it has none."""
    return session.scalars(
        select(MapVersion).where(MapVersion.site_id == site_id).order_by(MapVersion.version.desc()).limit(1)
    ).first()
