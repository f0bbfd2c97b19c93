"""The positions table's weekly partitions on a real PostgreSQL (migration 0018 and the retention's upkeep):
partitioned after migration, rows in their week's partition or the default one, history queries and
retention unchanged, expired weeks dropped whole, a downgrade and upgrade keep every row. SQLite keeps a plain
table."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta

import pytest
from alembic import command
from sqlalchemy import text

from driftmap.services import positions as position_service
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.retention import RetentionPolicy, apply_retention
from driftmap.store import position_partitions as parts
from driftmap.store.access_models import VehiclePosition
from driftmap.store.db import alembic_config
from driftmap.store.storage import Storage
from tests.postgres_server import revision_before_partitioning

NOW = datetime.now(UTC).replace(microsecond=0)
POLICY = RetentionPolicy(full_days=2.0, downsample_s=10.0, keep_days=30.0, catch_up_days=7.0)


@pytest.fixture
def pg(storage: Storage) -> Iterator[Storage]:
    """The test's migrated store, on PostgreSQL only."""
    if storage.db.engine.dialect.name != "postgresql":
        pytest.skip("the positions table is partitioned on PostgreSQL only (run with --database postgresql)")
    yield storage


def _vehicle(storage: Storage) -> int:
    with storage.db.session() as session:
        site = site_service.create_site(session, "north")
        vehicle, _token = vehicle_service.create_vehicle(session, "loader", site.id)
        return vehicle.id


def _add(storage: Storage, vehicle_id: int, received: list[datetime]) -> None:
    """One position per moment of ``received``, with ``t_s`` its POSIX time."""
    with storage.db.session() as session:
        for k, moment in enumerate(received):
            session.add(
                VehiclePosition(
                    vehicle_id=vehicle_id, t_s=moment.timestamp(), node=1, x_m=float(k), y_m=0.0,
                    confidence=0.9, matched=True, lost=False, received_at=moment,
                )
            )  # fmt: skip


def _where(storage: Storage) -> dict[int, str]:
    """Position id -> the partition holding it."""
    with storage.db.engine.connect() as connection:
        rows = connection.execute(text("SELECT id, tableoid::regclass::text FROM vehicle_positions"))
        return {int(row[0]): str(row[1]) for row in rows}


def _partitions(storage: Storage) -> dict[str, datetime]:
    with storage.db.engine.connect() as connection:
        return parts.partitions(connection)


def test_sqlite_keeps_a_plain_table(storage: Storage) -> None:
    with storage.db.engine.connect() as connection:
        assert parts.is_partitioned(connection) == (connection.dialect.name == "postgresql")


class TestMigratedTable:
    def test_partitioned_by_range_on_received_at_with_weeks_ahead(self, pg: Storage) -> None:
        with pg.db.engine.connect() as connection:
            strategy, key = connection.execute(
                text(
                    "SELECT p.partstrat, a.attname FROM pg_partitioned_table p JOIN pg_attribute a "
                    "ON a.attrelid = p.partrelid AND a.attnum = p.partattrs[0] "
                    "WHERE p.partrelid = 'vehicle_positions'::regclass"
                )
            ).one()
            default = connection.scalar(
                text("SELECT count(*) FROM pg_inherits WHERE inhrelid = to_regclass(:name)"),
                {"name": parts.DEFAULT_PARTITION},
            )
        assert (strategy, key) == ("r", "received_at")
        assert default == 1
        weeks = _partitions(pg)
        assert parts.partition_name(parts.week_start(NOW)) in weeks
        assert parts.partition_name(parts.week_start(NOW + parts.AHEAD)) in weeks

    def test_rows_land_in_their_week_or_the_default_partition(self, pg: Storage) -> None:
        vehicle_id = _vehicle(pg)
        moments = [NOW, NOW + timedelta(days=8), NOW - timedelta(days=400), NOW + timedelta(days=400)]
        _add(pg, vehicle_id, moments)
        where = sorted(_where(pg).items())
        assert [name for _id, name in where] == [
            parts.partition_name(parts.week_start(NOW)),
            parts.partition_name(parts.week_start(NOW + timedelta(days=8))),
            parts.DEFAULT_PARTITION,
            parts.DEFAULT_PARTITION,
        ]

    def test_history_queries_span_partitions(self, pg: Storage) -> None:
        vehicle_id = _vehicle(pg)
        moments = [NOW - timedelta(days=400), NOW, NOW + timedelta(days=8)]
        _add(pg, vehicle_id, moments)
        with pg.db.session() as session:
            history = position_service.history(session, vehicle_id)
            assert [p.received_at for p in history] == moments
            assert [p.seq for p in position_service.since(session, history[0].seq)] == [
                history[1].seq,
                history[2].seq,
            ]
            assert position_service.last_seq(session) == history[2].seq
            (latest,) = position_service.latest(session, stale_after_s=1e9)
            assert latest.position is not None and latest.position.seq == history[2].seq


class TestUpkeep:
    def test_a_new_week_takes_its_rows_out_of_the_default_partition(self, pg: Storage) -> None:
        vehicle_id = _vehicle(pg)
        old = NOW - timedelta(days=100)
        _add(pg, vehicle_id, [old])
        with pg.db.engine.begin() as connection:
            done = parts.upkeep(connection, old, None)
        assert parts.partition_name(parts.week_start(old)) in done.created
        assert list(_where(pg).values()) == [parts.partition_name(parts.week_start(old))]

    def test_retention_drops_expired_weeks_whole_and_deletes_the_rest(self, pg: Storage) -> None:
        vehicle_id = _vehicle(pg)
        expired = NOW - timedelta(days=60)
        with pg.db.engine.begin() as connection:
            parts.upkeep(connection, expired, None)
        _add(pg, vehicle_id, [expired, NOW - timedelta(days=400), NOW])
        with pg.db.session() as session:
            done = apply_retention(session, POLICY, NOW)
        expired_week = parts.partition_name(parts.week_start(expired))
        assert expired_week in done.partitions_dropped
        assert expired_week not in _partitions(pg)
        assert done.dropped == 1  # the 400-day-old row of the default partition, row by row
        assert list(_where(pg).values()) == [parts.partition_name(parts.week_start(NOW))]
        with pg.db.session() as session:
            assert position_service.history(session, vehicle_id)[0].received_at == NOW

    def test_thinning_stays_row_level(self, pg: Storage) -> None:
        vehicle_id = _vehicle(pg)
        start = (NOW - timedelta(days=3)).replace(second=0)  # a minute: six 10 s buckets
        with pg.db.engine.begin() as connection:
            parts.upkeep(connection, start, None)
        _add(pg, vehicle_id, [start + timedelta(seconds=0.5 * k) for k in range(120)])
        with pg.db.session() as session:
            done = apply_retention(session, POLICY, NOW)
        assert done.thinned == 120 - 6
        assert len(_where(pg)) == 6

    def test_a_thinned_week_is_rewritten_once_and_gives_its_disk_back(self, pg: Storage) -> None:
        vehicle_id = _vehicle(pg)
        week = parts.week_start(NOW - timedelta(days=10))
        with pg.db.engine.begin() as connection:
            parts.upkeep(connection, week, None)
        _add(pg, vehicle_id, [week + timedelta(days=1, seconds=0.1 * k) for k in range(20_000)])
        name = parts.partition_name(week)

        def size() -> int:
            with pg.db.engine.connect() as connection:
                return int(connection.scalar(text(f"SELECT pg_total_relation_size('{name}')")) or 0)

        full = size()
        policy = RetentionPolicy(full_days=2.0, downsample_s=10.0, keep_days=30.0, catch_up_days=14.0)
        with pg.db.session() as session:
            done = apply_retention(session, policy, NOW)
        assert done.thinned == 20_000 - 200 and done.partition_compacted == name
        assert size() < full / 10
        assert set(_where(pg).values()) == {name} and len(_where(pg)) == 200
        with pg.db.session() as session:
            again = apply_retention(session, policy, NOW)
            assert len(position_service.history(session, vehicle_id)) == 200
        assert again.thinned == 0 and again.partition_compacted != name  # (a later week may be due now)
        with pg.db.engine.connect() as connection:  # still a partition with its indexes and foreign keys
            indexes = connection.scalars(
                text("SELECT indexdef FROM pg_indexes WHERE tablename = :t"), {"t": name}
            )
            assert sorted(d.rsplit(" USING btree ", 1)[1] for d in indexes) == [
                "(id, received_at)",
                "(received_at)",
                "(vehicle_id, t_s)",
            ]
            assert (
                connection.scalar(
                    text(
                        "SELECT count(*) FROM pg_constraint WHERE conrelid = to_regclass(:t) AND contype = 'f'"
                    ),
                    {"t": name},
                )
                == 2
            )

    def test_one_worker_at_a_time_and_a_second_pass_does_nothing(self, pg: Storage) -> None:
        later = NOW + timedelta(days=30)
        with pg.db.engine.connect() as first, pg.db.engine.connect() as second:
            holding = parts.upkeep(first, later, None)
            assert holding.created  # the weeks up to later + AHEAD
            assert parts.upkeep(second, later, None) == parts.Upkeep((), (), locked=False)
            first.commit()
            second.rollback()
            assert parts.upkeep(second, later, None) == parts.Upkeep((), ())
            second.commit()


def test_downgrade_and_upgrade_keep_every_row(pg: Storage) -> None:
    vehicle_id = _vehicle(pg)
    _add(pg, vehicle_id, [NOW - timedelta(days=400), NOW - timedelta(days=3), NOW, NOW + timedelta(days=400)])
    before = _where(pg)
    config = alembic_config(pg.db.url)
    with pg.db.engine.begin() as connection:
        config.attributes["connection"] = connection
        command.downgrade(config, revision_before_partitioning(config))
    with pg.db.engine.connect() as connection:
        assert not parts.is_partitioned(connection)
    assert set(_where(pg)) == set(before) and set(_where(pg).values()) == {"vehicle_positions"}
    with pg.db.engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "head")
    after = _where(pg)
    assert set(after) == set(before)
    oldest, future = min(after), max(after)
    assert after[oldest] == parts.partition_name(parts.week_start(NOW - timedelta(days=400)))  # weeks from it
    assert after[future] == parts.DEFAULT_PARTITION
    _add(pg, vehicle_id, [NOW])
    assert max(_where(pg)) > max(before)  # the id sequence carries on
