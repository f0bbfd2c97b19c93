"""A content-addressed blob store on disk for frame images and original files.

A blob's name is the SHA-256 of its bytes; it lives at ``<root>/<aa>/<bb>/<sha256>``. Writes are
atomic (temporary file in the same directory, then ``os.replace``), so a reader never sees half a
blob. :meth:`BlobStore.batch` tracks the blobs one operation creates and removes them again if the
operation fails, so a failed import leaves no orphans.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from driftmap.errors import NotFoundError


class BlobBatch:
    """The blobs created during one operation; see :meth:`BlobStore.batch`."""

    def __init__(self, store: BlobStore) -> None:
        self._store = store
        self.created: list[str] = []

    def put(self, data: bytes) -> str:
        """Store ``data`` and return its SHA-256; remembers it when the blob is new."""
        sha, created = self._store.put(data)
        if created:
            self.created.append(sha)
        return sha


class BlobStore:
    """Content-addressed files under ``root``."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def path_of(self, sha256: str) -> Path:
        """Where the blob named ``sha256`` lives (whether or not it exists)."""
        if len(sha256) != 64 or any(c not in "0123456789abcdef" for c in sha256):
            raise NotFoundError(f"not a blob name: {sha256!r}")
        return self.root / sha256[:2] / sha256[2:4] / sha256

    def put(self, data: bytes) -> tuple[str, bool]:
        """Store ``data``; returns (sha256, True when this call created the blob)."""
        sha = hashlib.sha256(data).hexdigest()
        path = self.path_of(sha)
        if path.exists():
            return sha, False
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return sha, True

    def get(self, sha256: str) -> bytes:
        """The bytes of a stored blob."""
        path = self.path_of(sha256)
        try:
            return path.read_bytes()
        except FileNotFoundError as exc:
            raise NotFoundError(f"blob {sha256} is missing from {self.root}") from exc

    def exists(self, sha256: str) -> bool:
        return self.path_of(sha256).exists()

    def delete(self, sha256: str) -> None:
        """Remove a blob if present."""
        self.path_of(sha256).unlink(missing_ok=True)

    def all_names(self) -> set[str]:
        """The names of every stored blob (for tests and garbage collection)."""
        if not self.root.exists():
            return set()
        return {p.name for p in self.root.glob("??/??/*") if not p.name.startswith(".tmp-")}

    @contextmanager
    def batch(self) -> Iterator[BlobBatch]:
        """Track new blobs; on an exception inside the block, delete them and re-raise."""
        batch = BlobBatch(self)
        try:
            yield batch
        except BaseException:
            for sha in batch.created:
                self.delete(sha)
            raise
