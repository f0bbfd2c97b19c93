"""The API keeps its OpenAPI contract under fuzzing: schemathesis sends every operation of a real ``driftmap
serve``'s own ``/api/openapi.json`` a bounded number of requests, as an admin and as an anonymous client:
boundary values (as the admin), then generated ones valid by the schema and ones that break it somewhere.
Every answer must be no server error (5xx) and conform to the document: a documented status, its content
type, its body schema (dates with a time zone) and its documented headers.

The server is a throwaway (a copy of the built tiny site, no job worker), so the admin may delete what it finds. Left out,
because they would break the run rather than find a defect (tests/api/fuzzing.py):

* ``POST /api/auth/logout`` as the admin: it revokes the run's own token;
* ``PATCH``/``DELETE /api/users/{user_id}`` on the admin's own id (a change revokes its tokens): sent to a
  throwaway admin instead.

bench/fuzz_api.py runs the same at scale (25,000+ requests) and prints its figures.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.api.access_helpers import built_tiny_data, copy_data_to_new_database
from tests.api.fuzzing import FuzzServer, Principal, fuzz, fuzz_server
from tests.processes import driftmap_env

EXAMPLES = 6
"""Generated requests per operation and generation mode (about 1,000 requests per principal)."""
COVERAGE = 25
"""Coverage cases (boundary values) per operation as the admin, about 1,800 in all (without credentials they
would all be 401); bench/fuzz_api.py sends all of them (about 3,300)."""


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path) -> Iterator[FuzzServer]:
    """``driftmap serve`` on a private copy of the built tiny site (survey, drives, a map; on PostgreSQL a
    database of its own), so generated ids find rows to read, change and delete."""
    work = tmp_path_factory.mktemp("fuzz")
    data, database_url = copy_data_to_new_database(
        built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), work / "data"
    )
    with fuzz_server(driftmap_env(data, database_url), work / "serve.log") as running:
        yield running


def _principal(server: FuzzServer, name: str) -> Principal:
    return server.admin if name == "admin" else server.anonymous


@pytest.mark.parametrize("who", ["admin", "anonymous"])
def test_no_server_error_and_no_schema_violation(server: FuzzServer, who: str) -> None:
    tally = fuzz(server, _principal(server, who), EXAMPLES, coverage=COVERAGE if who == "admin" else 0)
    assert tally.requests > 40 * EXAMPLES, tally.summary()
    assert tally.server_errors == 0 and tally.violations == 0, tally.report()
    assert server.process.poll() is None, server.log.read_text()[-4000:]
