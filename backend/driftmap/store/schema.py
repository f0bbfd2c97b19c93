"""The whole schema: importing this module registers every model module on ``Base.metadata``.

Model modules split by domain (map data in :mod:`driftmap.store.models`, jobs, users and vehicles in their
own modules) all derive from :class:`driftmap.store.models.Base`; Alembic and the schema test read
:data:`metadata` from here so no table is forgotten.
"""

from __future__ import annotations

from driftmap.store import (
    access_models,  # noqa: F401 (registers users, vehicles, positions, live states)
    event_models,  # noqa: F401 (registers the events table)
    job_models,  # noqa: F401 (registers the jobs table)
    models,
    worker_models,  # noqa: F401 (registers the workers table)
)
from driftmap.store.position_partitions import is_partition_name

metadata = models.Base.metadata

__all__ = ["include_name", "metadata"]


def include_name(name: str | None, type_: str, parent_names: object) -> bool:
    """Alembic's ``include_name`` hook: the positions' partitions (PostgreSQL) are not model tables."""
    return not (type_ == "table" and name is not None and is_partition_name(name))
