"""The pair every service needs: the database and the blob store, opened from settings."""

from __future__ import annotations

from dataclasses import dataclass

from driftmap.config import Settings
from driftmap.store.blobs import BlobStore
from driftmap.store.db import Database


@dataclass
class Storage:
    """An open database (schema upgraded) and the blob store beside it."""

    db: Database
    blobs: BlobStore

    @classmethod
    def open(cls, settings: Settings, *, upgrade: bool = True) -> Storage:
        """Open the configured database and blob store; upgrade the schema unless told not to."""
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        db = Database(settings.resolved_database_url())
        if upgrade:
            db.upgrade()
        return cls(db=db, blobs=BlobStore(settings.blob_dir))

    def close(self) -> None:
        self.db.dispose()
