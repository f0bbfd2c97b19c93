"""The content-addressed blob store."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from driftmap.errors import NotFoundError
from driftmap.store.blobs import BlobStore


class TestPutGet:
    def test_name_is_sha256_and_bytes_round_trip(self, tmp_path: Path) -> None:
        store = BlobStore(tmp_path)
        sha, created = store.put(b"frame bytes")
        assert sha == hashlib.sha256(b"frame bytes").hexdigest()
        assert created
        assert store.get(sha) == b"frame bytes"
        assert store.path_of(sha).parent.parent.name == sha[:2]

    def test_same_content_is_stored_once(self, tmp_path: Path) -> None:
        store = BlobStore(tmp_path)
        first, created_first = store.put(b"x" * 100)
        second, created_second = store.put(b"x" * 100)
        assert first == second
        assert created_first and not created_second
        assert store.all_names() == {first}

    def test_no_temporary_files_left(self, tmp_path: Path) -> None:
        store = BlobStore(tmp_path)
        for i in range(20):
            store.put(bytes([i]) * 10)
        leftovers = [p for p in tmp_path.rglob("*") if p.name.startswith(".tmp-")]
        assert leftovers == []

    def test_missing_and_malformed_names(self, tmp_path: Path) -> None:
        store = BlobStore(tmp_path)
        with pytest.raises(NotFoundError, match="missing"):
            store.get("0" * 64)
        with pytest.raises(NotFoundError, match="not a blob name"):
            store.get("../../etc/passwd")


class TestBatch:
    def test_failure_removes_only_new_blobs(self, tmp_path: Path) -> None:
        store = BlobStore(tmp_path)
        kept, _ = store.put(b"shared with an earlier import")
        with pytest.raises(RuntimeError), store.batch() as batch:
            batch.put(b"shared with an earlier import")
            batch.put(b"new one")
            raise RuntimeError("import failed")
        assert store.all_names() == {kept}

    def test_success_keeps_blobs(self, tmp_path: Path) -> None:
        store = BlobStore(tmp_path)
        with store.batch() as batch:
            sha = batch.put(b"kept")
        assert store.exists(sha)
