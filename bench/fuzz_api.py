"""Fuzzing benchmark: schemathesis against a real ``driftmap serve``, every operation, as admin and anonymous.

The engine of tests/api/test_fuzz_contract.py (tests/api/fuzzing.py) at scale: simulates the tiny site, builds
its FAST map into a throwaway data dir, starts ``driftmap serve --no-worker`` on it, and sends every operation
of the server's ``/api/openapi.json`` generated requests (positive and negative generation modes, a random
seed unless ``--seed``) until at least ``--requests`` in total, half as an admin (first every coverage case:
boundary values), half without credentials.
Every answer is checked for no server error and conformance to the document (status, content type, body
schema, headers). Prints, per principal and in total: requests sent, server errors, schema violations,
requests per second, answers by status, and the server's peak resident memory (VmHWM of the server process).
Target (issue 25): 0 server errors in 25,000+ fuzzed requests as admin and as anonymous.

Usage: ``PYTHONPATH=backend .venv/bin/python bench/fuzz_api.py [--requests 25000] [--seed N] [--postgresql]``
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.api.access_helpers import built_tiny_data, copy_data_to_new_database
from tests.api.fuzzing import MODES, FuzzServer, Tally, fuzz, fuzz_server
from tests.postgres_server import PostgresServer, postgres_bin_dir, set_active_server
from tests.processes import driftmap_env
from tests.sim_site import make_tiny_site

TARGET_SERVER_ERRORS = 0
COVERAGE = 10_000
"""Coverage cases (boundary values) per operation in the admin's first round: all of them."""


def peak_rss_mib(pid: int) -> float:
    """The peak resident set size (VmHWM) of process ``pid``, in MiB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


@contextlib.contextmanager
def private_postgresql() -> Iterator[None]:
    """A private PostgreSQL server (tests/postgres_server.py) that the built site and the served copy of it
    go to (``built_tiny_data`` and ``copy_data_to_new_database`` use the active server)."""
    bin_dir = postgres_bin_dir()
    if bin_dir is None:
        sys.exit("PostgreSQL is not installed (make system-packages installs it)")
    server = PostgresServer(bin_dir)
    server.start()
    try:
        server.prepare_template()
        set_active_server(server)
        yield
    finally:
        set_active_server(None)
        server.stop()


def run(server: FuzzServer, requests: int, seed: int | None) -> list[tuple[str, Tally]]:
    """Fuzz as the admin, then as anonymous, until each has sent ``requests / 2``: rounds over every operation
    (operations without parameters have no negative requests, and small input spaces run out early)."""
    operations = sum(1 for _ in server.schema().get_all_operations())
    tallies = []
    for principal in (server.admin, server.anonymous):
        tally = Tally()
        rounds = 0
        while tally.requests < requests / 2:
            examples = max(1, math.ceil((requests / 2 - tally.requests) / (operations * len(MODES))))
            coverage = COVERAGE if rounds == 0 and principal is server.admin else 0
            fuzz(
                server,
                principal,
                examples,
                coverage=coverage,
                seed=None if seed is None else seed + rounds,
                tally=tally,
            )
            rounds += 1
        print(
            f"{principal.name}: {tally.summary()}; {tally.requests / tally.elapsed_s:.0f} requests/s "
            f"({operations} operations, {rounds} rounds)"
        )
        if tally.reports:
            print(tally.report())
        tallies.append((principal.name, tally))
    return tallies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=25_000, help="at least this many requests in total")
    parser.add_argument("--seed", type=int, default=None, help="a fixed generation seed (default: random)")
    parser.add_argument(
        "--postgresql", action="store_true", help="on a private PostgreSQL server (default: SQLite)"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="driftmap-bench-fuzz-") as tmp, contextlib.ExitStack() as stack:
        work = Path(tmp)
        if args.postgresql:
            stack.enter_context(private_postgresql())
        t0 = time.perf_counter()
        data = built_tiny_data(work, make_tiny_site(work / "site"))
        print(f"tiny site simulated, imported and mapped in {time.perf_counter() - t0:.0f} s")
        # the served copy (on PostgreSQL with a database of its own)
        data, database_url = copy_data_to_new_database(data, work / "served")
        with fuzz_server(driftmap_env(data, database_url), work / "serve.log") as server:
            tallies = run(server, args.requests, args.seed)
            rss = peak_rss_mib(server.process.pid)
            alive = server.process.poll() is None
        sent = sum(t.requests for _, t in tallies)
        errors = sum(t.server_errors for _, t in tallies)
        violations = sum(t.violations for _, t in tallies)
        seconds = sum(t.elapsed_s for _, t in tallies)
        print()
        print("| principal | requests | server errors | schema violations | requests/s |")
        print("|---|---|---|---|---|")
        for name, t in tallies:
            print(
                f"| {name} | {t.requests:,} | {t.server_errors} | {t.violations} | "
                f"{t.requests / t.elapsed_s:.0f} |"
            )
        print(f"| total | {sent:,} | {errors} | {violations} | {sent / seconds:.0f} |")
        print(f"server peak RSS: {rss:.0f} MiB; server still running: {alive}")
        if errors > TARGET_SERVER_ERRORS or violations or not alive:
            sys.exit(1)


if __name__ == "__main__":
    main()
