"""The jobs table's rules that the database itself enforces."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import IntegrityError

from driftmap.services import sites as site_service
from driftmap.store.job_models import Job
from driftmap.store.storage import Storage


def _site(storage: Storage, name: str) -> int:
    with storage.db.session() as session:
        return site_service.create_site(session, name).id


def _add(storage: Storage, site_id: int | None, status: str, kind: str = "map.build") -> None:
    with storage.db.session() as session:
        session.add(Job(kind=kind, site_id=site_id, args={}, status=status))


class TestOneUnfinishedBuildPerSite:
    def test_a_second_queued_or_running_build_of_a_site_is_refused(self, storage: Storage) -> None:
        site = _site(storage, "a")
        _add(storage, site, "running")
        for status in ("queued", "running"):
            with pytest.raises(IntegrityError):
                _add(storage, site, status)

    def test_ended_builds_other_sites_and_other_kinds_do_not_count(self, storage: Storage) -> None:
        first, other = _site(storage, "a"), _site(storage, "b")
        for status in ("succeeded", "failed", "cancelled", "queued"):
            _add(storage, first, status)
        _add(storage, other, "queued")
        _add(storage, first, "queued", kind="drive.localise")
        _add(storage, None, "queued")
        _add(storage, None, "queued")
        with storage.db.session() as session:
            assert session.query(Job).count() == 8
