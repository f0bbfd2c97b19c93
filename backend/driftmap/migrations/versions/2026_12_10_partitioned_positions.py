"""vehicle_positions: on PostgreSQL, partitioned by RANGE on received_at, one partition per UTC week

Revision ID: 0018
Revises: 0017
Create Date: 2026-12-10 09:00:00.000000

One partition per week (Monday 00:00 UTC to the next), named ``vehicle_positions_wYYYYMMDD`` after its Monday,
plus the default partition ``vehicle_positions_default`` for any row no week covers, so no insert can fail.
Weeks rather than days: history queries select by the vehicle's clock ``t_s``, which cannot prune partitions,
so each query plans and probes every partition; a year of history is about 55 weekly partitions against about
370 daily ones, which add about 130 ms to a one-hour history query (docs/operations.md, Position history);
the retention still frees a whole week with one ``DROP TABLE``. The job workers' retention pass creates the
coming weeks' partitions and drops the expired ones (:mod:`driftmap.store.position_partitions` uses the same
names).

PostgreSQL requires a partitioned table's primary key to hold the partition key: it becomes
``(id, received_at)``; ``id`` stays the unique sequence number the live WebSocket resumes from (one sequence for
every partition). The foreign keys, the two indexes and the column defaults are kept. The upgrade copies every
row into the new table (weekly partitions from the oldest row's week to two weeks ahead); on a large history
this takes a while and holds the positions table locked. SQLite keeps a plain table: nothing is done there.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import sqlalchemy as sa
from alembic import op

revision = "0018"
down_revision = "0017"
branch_labels = None
depends_on = None

WEEK = timedelta(days=7)
AHEAD = timedelta(days=14)
COLUMNS_FROM = "(LIKE {source} INCLUDING DEFAULTS INCLUDING CONSTRAINTS)"


def _constraints(table: str, primary_key: str) -> None:
    """The primary key, foreign keys and indexes of the model, on ``table`` (named ``vehicle_positions``)."""
    op.execute(f"ALTER TABLE {table} ADD CONSTRAINT pk_vehicle_positions PRIMARY KEY ({primary_key})")
    op.execute(
        f"ALTER TABLE {table} ADD CONSTRAINT fk_vehicle_positions_vehicle_id_vehicles "
        "FOREIGN KEY (vehicle_id) REFERENCES vehicles (id) ON DELETE CASCADE"
    )
    op.execute(
        f"ALTER TABLE {table} ADD CONSTRAINT fk_vehicle_positions_map_version_id_map_versions "
        "FOREIGN KEY (map_version_id) REFERENCES map_versions (id) ON DELETE SET NULL"
    )
    op.execute(f"CREATE INDEX ix_vehicle_positions_vehicle_id_t_s ON {table} (vehicle_id, t_s)")
    op.execute(f"CREATE INDEX ix_vehicle_positions_received_at ON {table} (received_at)")


def _set_aside(old: str) -> str:
    """Rename ``vehicle_positions`` and its index names to ``old``; returns the id sequence's name."""
    op.execute(f"ALTER TABLE vehicle_positions RENAME TO {old}")
    op.execute(f"ALTER TABLE {old} RENAME CONSTRAINT pk_vehicle_positions TO pk_{old}")
    op.execute(f"ALTER INDEX ix_vehicle_positions_vehicle_id_t_s RENAME TO ix_{old}_vehicle_id_t_s")
    op.execute(f"ALTER INDEX ix_vehicle_positions_received_at RENAME TO ix_{old}_received_at")
    sequence = op.get_bind().scalar(sa.text(f"SELECT pg_get_serial_sequence('{old}', 'id')"))
    if sequence is None:
        raise RuntimeError(f"{old}.id has no sequence: not the schema this migration expects")
    return str(sequence)


def _take_over(old: str, sequence: str) -> None:
    """Copy every row of ``old`` into the new ``vehicle_positions``, hand it the id sequence, drop ``old``."""
    op.execute(f"INSERT INTO vehicle_positions SELECT * FROM {old}")
    op.execute(f"ALTER SEQUENCE {sequence} OWNED BY vehicle_positions.id")
    op.execute(f"DROP TABLE {old}")


def _week_start(moment: datetime) -> datetime:
    day = moment.astimezone(UTC).replace(hour=0, minute=0, second=0, microsecond=0)
    return day - timedelta(days=day.weekday())


def _literal(moment: datetime) -> str:
    return f"'{moment:%Y-%m-%d %H:%M:%S}+00'::timestamptz"


def upgrade() -> None:
    bind = op.get_bind()
    if bind.dialect.name != "postgresql":
        return
    sequence = _set_aside("vehicle_positions_plain")
    op.execute(f"CREATE TABLE vehicle_positions {COLUMNS_FROM.format(source='vehicle_positions_plain')} "
               "PARTITION BY RANGE (received_at)")  # fmt: skip
    op.execute("CREATE TABLE vehicle_positions_default PARTITION OF vehicle_positions DEFAULT")
    now = datetime.now(UTC)
    oldest = bind.scalar(sa.text("SELECT min(received_at) FROM vehicle_positions_plain"))
    start = _week_start(min(oldest, now) if oldest is not None else now)
    while start <= now + AHEAD:
        op.execute(
            f"CREATE TABLE vehicle_positions_w{start:%Y%m%d} PARTITION OF vehicle_positions "
            f"FOR VALUES FROM ({_literal(start)}) TO ({_literal(start + WEEK)})"
        )
        start += WEEK
    _take_over("vehicle_positions_plain", sequence)
    _constraints("vehicle_positions", "id, received_at")  # after the copy: one index build per partition


def downgrade() -> None:
    if op.get_bind().dialect.name != "postgresql":
        return
    sequence = _set_aside("vehicle_positions_partitioned")
    op.execute(
        f"CREATE TABLE vehicle_positions {COLUMNS_FROM.format(source='vehicle_positions_partitioned')}"
    )
    _take_over("vehicle_positions_partitioned", sequence)  # its partitions go with it
    _constraints("vehicle_positions", "id")
