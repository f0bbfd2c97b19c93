"""bench_history.py on PostgreSQL: bytes per position row and one-hour history queries, partitioned vs plain.

Two databases on one private server (tests.postgres_server): ``partitioned`` at the newest schema (the positions
table partitioned by week of ``received_at``, migration 0018) and ``plain`` at the schema before it (one
table). Both get the same rows by COPY: ``vehicles`` vehicles, ``hours`` each at 10 positions a
second with every column filled, vehicle ``v``'s hours received ``v mod 30`` days ago, so the rows spread over
the weekly partitions of a month. Then, for each table: its bytes per row (``pg_total_relation_size`` of the
table and of every partition, indexes and TOAST included, after VACUUM ANALYZE), and the median of ``runs``
one-hour history queries of one vehicle through :func:`driftmap.services.positions.history` with the API's
largest page (a new session each, as a request has), and PostgreSQL's own planning and execution times of that
query; and every vehicle's latest position against finding each one's newest by grouping the whole table. On the partitioned table it then times the same hour as the API answers it (``GET
/api/vehicles/{id}/positions`` of a real ``driftmap serve`` on that database, median of ``runs``) and, in this
process on the same rows, the JSON encoding of the positions against encoding them through a validated
:class:`~driftmap.api.schemas_access.PositionRead` per row. ``--extra-partitions N`` then adds N empty one-day partitions to the partitioned table and times the
query on the server again (the cost of many partitions: a year of daily ones against weekly ones).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import httpx
from alembic import command
from pydantic import TypeAdapter
from sqlalchemy import text
from tests.postgres_server import PostgresServer, postgres_bin_dir, revision_before_partitioning

from bench_live import serving
from driftmap.api.schemas_access import PositionRead, position_list_json
from driftmap.services import positions as position_service
from driftmap.services import sites as site_service
from driftmap.services import users as user_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.retention import RetentionPolicy
from driftmap.store import position_partitions as parts
from driftmap.store.db import Database, alembic_config

FPS = 10.0
DAY_S = 86_400.0
SPREAD_DAYS = 30
CLOCK0_S = 1_000_000.0
"""Every vehicle's clock ``t_s`` at the start of its hours (the vehicles' clocks are their own)."""
COLUMNS = (
    "vehicle_id, map_version_id, t_s, node, x_m, y_m, yaw_rad, confidence, matched, lost, received_at, "
    "obscured, obscured_reason, salient, sharpness, speckle, flat_area, speed_mps, moving, odometry"
)
EXPLAIN = (
    "EXPLAIN (ANALYZE, FORMAT JSON) SELECT p.*, v.name, v.site_id, m.version FROM vehicle_positions p "
    "JOIN vehicles v ON p.vehicle_id = v.id LEFT JOIN map_versions m ON p.map_version_id = m.id "
    "WHERE p.vehicle_id = :vehicle AND p.t_s >= :begin AND p.t_s <= :end ORDER BY p.t_s LIMIT 100000"
)
"""The history query's SQL (as :func:`driftmap.services.positions.history` sends it), for the server's own
planning and execution times."""

NEWEST_BY_SCAN = "SELECT vehicle_id, max(id) FROM vehicle_positions GROUP BY vehicle_id"
"""Every vehicle's newest position id from the whole table, for comparison with
:func:`driftmap.services.positions.latest`'s search of each vehicle's newest through its index."""


def run_postgresql(hours: float, vehicles: int, runs: int, extra_partitions: int = 0) -> None:
    """Measure and print (see the module doc)."""
    bin_dir = postgres_bin_dir()
    if bin_dir is None:
        sys.exit("PostgreSQL is not installed (make system-packages)")
    server = PostgresServer(bin_dir)
    server.start()
    now = datetime.now(UTC)
    try:
        figures = {}
        plain = revision_before_partitioning(alembic_config(server.url()))
        for name, revision in (("partitioned", "head"), ("plain", plain)):
            database = Database(server.create_database(name))
            try:
                figures[name] = _measure(database, revision, now, hours, vehicles, runs)
                if name == "partitioned":
                    figures["api"] = _api_answer(database, figures[name], runs)
                if name == "partitioned" and extra_partitions:
                    figures["more partitions"] = _with_more_partitions(
                        database, figures[name], extra_partitions
                    )
            finally:
                database.dispose()
    finally:
        server.stop()
    _report(figures, hours, vehicles, runs)


def _measure(
    database: Database, revision: str, now: datetime, hours: float, vehicles: int, runs: int
) -> dict[str, float]:
    """Migrate ``database`` to ``revision``, fill it, and measure: rows, bytes, write and query seconds."""
    config = alembic_config(database.url)
    with database.engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, revision)
        if parts.is_partitioned(connection):  # the month's weeks, as the workers' passes would have made them
            for days in range(SPREAD_DAYS + 7, 0, -7):
                parts.upkeep(connection, now - timedelta(days=days), None)
    with database.session() as session:
        site = site_service.create_site(session, "bench")
        ids = [vehicle_service.create_vehicle(session, f"v{k:02d}", site.id)[0].id for k in range(vehicles)]
    per_vehicle = int(hours * 3600 * FPS)
    t0 = time.perf_counter()
    raw = database.engine.raw_connection()
    try:
        pg = raw.driver_connection
        assert pg is not None
        with pg.cursor() as cursor, cursor.copy(f"COPY vehicle_positions ({COLUMNS}) FROM STDIN") as copy:
            for v, vehicle_id in enumerate(ids):
                start = now - timedelta(days=v % SPREAD_DAYS, hours=hours)
                for k in range(per_vehicle):
                    t = k / FPS
                    copy.write_row(
                        (vehicle_id, None, CLOCK0_S + t, k % 300, 13_000.0 + 0.3 * (k % 5000),
                         56_000.0 + 0.1 * (k % 7000), 0.01 * (k % 628), 0.97, True, False,
                         start + timedelta(seconds=t), False, None, 0.4, 0.8, 0.01, 0.1, 3.2, True, True)
                    )  # fmt: skip
        raw.commit()
    finally:
        raw.close()
    write_s = time.perf_counter() - t0
    with database.engine.connect() as connection:
        connection.execution_options(isolation_level="AUTOCOMMIT").execute(
            text("VACUUM ANALYZE vehicle_positions")
        )
        size = connection.scalar(
            text(
                "SELECT pg_total_relation_size('vehicle_positions') + coalesce((SELECT "
                "sum(pg_total_relation_size(inhrelid)) FROM pg_inherits "
                "WHERE inhparent = 'vehicle_positions'::regclass), 0)"
            )
        )
        partitions = connection.scalar(
            text("SELECT count(*) FROM pg_inherits WHERE inhparent = 'vehicle_positions'::regclass")
        )
    rows = per_vehicle * vehicles
    vehicle_id = ids[len(ids) // 2]
    begin_s = CLOCK0_S + min(1800.0, max(0.0, hours * 3600 - 3600))
    times, cpu, found = [], [], 0
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        with database.session() as session:
            found = len(
                position_service.history(session, vehicle_id, begin_s, begin_s + 3600 - 0.5 / FPS, 100_000)
            )
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    planning, execution = _server_s(database, vehicle_id, begin_s, runs)
    latest, newest_by_scan = [], []
    for _ in range(runs):
        with database.session() as session:
            t0 = time.perf_counter()
            position_service.latest(session, 30.0)
            latest.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            session.execute(text(NEWEST_BY_SCAN)).all()
            newest_by_scan.append(time.perf_counter() - t0)
    return {
        "latest_s": statistics.median(latest),
        "newest_by_scan_s": statistics.median(newest_by_scan),
        "rows": rows,
        "bytes": float(size or 0),
        "write_s": write_s,
        "query_s": statistics.median(times),
        "query_cpu_s": statistics.median(cpu),
        "server_s": planning + execution,
        "planning_s": planning,
        "vehicle_id": vehicle_id,
        "begin_s": begin_s,
        "found": found,
        "partitions": float(partitions or 0),
    }


def _api_answer(database: Database, measured: dict[str, float], runs: int) -> dict[str, float]:
    """The one-hour history as the API answers it over HTTP, and its JSON encoding in this process against
    encoding a validated ``PositionRead`` per row (median seconds of ``runs``)."""
    vehicle_id, begin_s = int(measured["vehicle_id"]), measured["begin_s"]
    with database.session() as session:
        user_service.create_user(session, "bench", "bench-password", "admin")
        views = position_service.history(session, vehicle_id, begin_s, begin_s + 3600 - 0.5 / FPS, 100_000)
    validated = TypeAdapter(list[PositionRead])
    encode, encode_validated = [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        fast = position_list_json(views)
        encode.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        slow = validated.dump_json([PositionRead.model_validate(view) for view in views])
        encode_validated.append(time.perf_counter() - t0)
    if TypeAdapter(list[dict[str, object]]).validate_json(fast) != validated.dump_python(
        validated.validate_json(slow), mode="json"
    ):
        sys.exit("the API's JSON of the positions differs from PositionRead's")
    params = {"start": begin_s, "end": begin_s + 3600 - 0.5 / FPS, "limit": 100_000}
    answers, found = [], 0
    with (
        tempfile.TemporaryDirectory(prefix="driftmap-history-") as work,
        serving(Path(work), Path(work), "--no-worker", env={"DRIFTMAP_DATABASE_URL": database.url}) as (
            base,
            _pid,
        ),
        httpx.Client(base_url=base, timeout=60.0) as client,
    ):
        login = client.post("/api/auth/login", json={"username": "bench", "password": "bench-password"})
        client.headers["Authorization"] = f"Bearer {login.json()['access_token']}"
        for _ in range(runs + 1):  # the first warms the server's caches and connections
            t0 = time.perf_counter()
            answer = client.get(f"/api/vehicles/{vehicle_id}/positions", params=params)
            answers.append(time.perf_counter() - t0)
            answer.raise_for_status()
            found = len(answer.json())
    return {
        "answer_s": statistics.median(answers[1:]),
        "found": found,
        "encode_s": statistics.median(encode),
        "encode_validated_s": statistics.median(encode_validated),
    }


def _server_s(database: Database, vehicle_id: int, begin_s: float, runs: int) -> tuple[float, float]:
    """Median planning and execution seconds of the history query of ``vehicle_id`` from ``begin_s``."""
    planning, execution = [], []
    with database.engine.connect() as connection:
        for _ in range(runs):
            (plan,) = connection.scalar(
                text(EXPLAIN), {"vehicle": vehicle_id, "begin": begin_s, "end": begin_s + 3600 - 0.5 / FPS}
            )
            planning.append(plan["Planning Time"] / 1000.0)
            execution.append(plan["Execution Time"] / 1000.0)
    return statistics.median(planning), statistics.median(execution)


def _with_more_partitions(database: Database, measured: dict[str, float], extra: int) -> dict[str, float]:
    """The history query's server time after ``extra`` empty one-day partitions are added (ahead of any row)."""
    first = parts.week_start(datetime.now(UTC)) + timedelta(days=400)
    with database.engine.begin() as connection:
        for k in range(extra):
            lower = first + timedelta(days=k)
            connection.execute(
                text(
                    f"CREATE TABLE bench_empty_{k} PARTITION OF vehicle_positions FOR VALUES FROM "
                    f"('{lower:%Y-%m-%d}+00') TO ('{lower + timedelta(days=1):%Y-%m-%d}+00')"
                )
            )
    planning, execution = _server_s(database, int(measured["vehicle_id"]), measured["begin_s"], 7)
    return {
        **measured,
        "partitions": measured["partitions"] + extra,
        "planning_s": planning,
        "server_s": planning + execution,
    }


def _report(figures: dict[str, dict[str, float]], hours: float, vehicles: int, runs: int) -> None:
    policy = RetentionPolicy()
    part, plain = figures["partitioned"], figures["plain"]
    print(
        f"{part['rows']:,.0f} positions ({vehicles} vehicles x {hours:g} h at {FPS:g}/s, spread over "
        f"{SPREAD_DAYS} days) copied in: partitioned {part['write_s']:.0f} s ({part['partitions']:.0f} partitions), "
        f"plain {plain['write_s']:.0f} s"
    )
    full_days = policy.full_days
    thinned_days = SPREAD_DAYS - full_days
    month_rows = vehicles * (full_days * DAY_S * FPS + thinned_days * DAY_S / policy.downsample_s)
    for name in ("partitioned", "plain"):
        f = figures[name]
        per_row = f["bytes"] / f["rows"]
        print(
            f"{name}: {per_row:.0f} bytes per position row (table + indexes); 30 days of {vehicles} vehicles "
            f"under the default retention ({full_days:g} days full, {thinned_days:g} thinned to one per "
            f"{policy.downsample_s:g} s: {month_rows / 1e6:,.0f} M rows): {month_rows * per_row / 1e9:,.0f} GB"
        )
    for name in ("partitioned", "plain"):
        f = figures[name]
        print(
            f"{name}: one-hour history of one vehicle ({f['found']:,.0f} positions through positions.history), "
            f"median of {runs} in this process: {f['query_s'] * 1000:.0f} ms, of which its CPU "
            f"{f['query_cpu_s'] * 1000:.0f} ms; the server plans and runs it in {f['server_s'] * 1000:.0f} ms"
        )
    print(f"ratio partitioned / plain: bytes per row {part['bytes'] / part['rows'] / (plain['bytes'] / plain['rows']):.2f}, "
          f"history query {part['query_s'] / plain['query_s']:.2f}, on the server "
          f"{part['server_s'] / plain['server_s']:.2f}")  # fmt: skip
    for name in ("partitioned", "plain"):
        f = figures[name]
        print(
            f"{name}: every vehicle's latest position (positions.latest) {f['latest_s'] * 1000:.1f} ms; finding "
            f"each vehicle's newest id by grouping the whole table {f['newest_by_scan_s'] * 1000:.0f} ms "
            f"(ratio {f['newest_by_scan_s'] / f['latest_s']:.0f}x)"
        )
    api = figures["api"]
    print(
        f"the API answers that hour ({api['found']:,.0f} positions, GET /api/vehicles/{{id}}/positions over HTTP) in "
        f"{api['answer_s'] * 1000:.0f} ms (median of {runs}; target < 200 ms); encoding it as JSON "
        f"{api['encode_s'] * 1000:.0f} ms, through a validated PositionRead per row "
        f"{api['encode_validated_s'] * 1000:.0f} ms (ratio {api['encode_validated_s'] / api['encode_s']:.1f}x)"
    )
    for name in ("partitioned", "more partitions"):
        if name in figures:
            f = figures[name]
            print(f"{name} ({f['partitions']:.0f}): the server plans the history query in {f['planning_s'] * 1000:.1f} ms "
                  f"and plans and runs it in {f['server_s'] * 1000:.0f} ms")  # fmt: skip
