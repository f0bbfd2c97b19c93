"""``GET /api/health``: open to everyone, for load balancers and start-up scripts."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel
from sqlalchemy import text

from driftmap import __version__
from driftmap.api.deps import StorageDep

router = APIRouter(tags=["health"])


class Health(BaseModel):
    status: str
    version: str


@router.get("/health")
def health(storage: StorageDep) -> Health:
    """Whether the server is up and its database answers."""
    with storage.db.engine.connect() as connection:
        connection.execute(text("SELECT 1"))
    return Health(status="ok", version=__version__)
