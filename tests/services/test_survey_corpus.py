"""Every plan of a DXF corpus (tests/services/dxf_corpus.py) is imported or refused with a reason; none crashes.

Imported through :func:`driftmap.services.sites.add_survey_map` into a real database, so the stored levels
and the constraints are exercised too.
"""

from __future__ import annotations

import time
from collections import Counter

import pytest

from driftmap.errors import BadInputError
from driftmap.services import sites as site_service
from driftmap.store.storage import Storage
from tests.services.dxf_corpus import CorpusFile, corpus

CORPUS_S = 30.0  # the whole corpus imports within this time, seconds (a few on a free 2-core machine)


@pytest.fixture(scope="module")
def files() -> list[CorpusFile]:
    return list(corpus())


def import_or_reason(storage: Storage, plan: CorpusFile) -> str | None:
    """None when ``plan`` was imported, else the reason it was refused (any other exception propagates)."""
    try:
        with storage.blobs.batch() as batch, storage.db.session() as session:
            site = site_service.get_site(session, "corpus")
            site_service.add_survey_map(session, batch, site, plan.data, plan.name)
    except BadInputError as exc:
        assert exc.file == plan.name and exc.reason, plan.name
        return exc.reason
    return None


def test_the_corpus_covers_versions_encodings_and_outcomes(files: list[CorpusFile]) -> None:
    assert len(files) > 100
    names = " ".join(f.name for f in files)
    for part in ("R12", "R2000", "R2004", "R2007", "R2010", "R2013", "R2018", "binary", "crlf", "cp1252"):
        assert part in names
    assert Counter(f.importable for f in files)[False] > 20


def test_every_plan_is_imported_or_refused_with_a_reason(storage: Storage, files: list[CorpusFile]) -> None:
    with storage.db.session() as session:
        site_service.create_site(session, "corpus")
    start = time.perf_counter()
    wrong = []
    for plan in files:
        reason = import_or_reason(storage, plan)
        if (reason is None) != plan.importable:
            wrong.append(f"{plan.name}: {'imported' if reason is None else reason}")
    assert not wrong, "\n".join(wrong)
    assert time.perf_counter() - start < CORPUS_S
