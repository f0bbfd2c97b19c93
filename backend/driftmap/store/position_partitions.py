"""The position table's weekly partitions on PostgreSQL: create the coming weeks', drop the expired ones.

On PostgreSQL ``vehicle_positions`` is partitioned by RANGE on ``received_at`` (migration 0018): one
partition per UTC week starting Monday 00:00, named ``vehicle_positions_wYYYYMMDD`` after that Monday, plus
``vehicle_positions_default`` for a row no weekly partition covers (so no insert can fail). SQLite keeps a
plain table and none of this applies (:func:`is_partitioned` is False).

Why weeks: history queries select by the vehicle's own clock ``t_s``, not by ``received_at``, so they cannot
be pruned and visit every partition; a year's history is then about 55 partitions to plan and probe instead of
about 370 daily ones, while dropping a week at once still frees a week's rows without deleting them.

The retention pass (:func:`driftmap.services.retention.apply_retention`) calls :func:`upkeep`, which is
idempotent and safe with several workers: it runs only under a transaction-scoped advisory lock (a worker that
does not get it leaves the upkeep to the one that has it), skips partitions that exist already, and creates a
partition as a plain table that it then attaches (rows the default partition holds for that week move into
it first), which locks the parent less than ``CREATE TABLE ... PARTITION OF`` would.

Thinning deletes 99 % of a week's rows but frees no disk: nothing is ever inserted into a past week again, so
its pages are never reused. :func:`compact` therefore rewrites one thinned week per pass: its surviving rows
are copied into a new table with the same indexes, foreign keys and a CHECK of the week's bounds, which then
replaces the old partition (detach, attach, drop: the parent is locked exclusively only for those catalog
changes, not for the copy). A compacted week carries the table comment :data:`COMPACTED`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from sqlalchemy import Connection, text

__all__ = [
    "AHEAD",
    "DEFAULT_PARTITION",
    "PARENT",
    "WEEK",
    "Upkeep",
    "compact",
    "is_partition_name",
    "is_partitioned",
    "partition_name",
    "partitions",
    "upkeep",
    "week_start",
]

PARENT = "vehicle_positions"
DEFAULT_PARTITION = f"{PARENT}_default"
WEEK = timedelta(days=7)
AHEAD = timedelta(days=14)
"""Partitions exist up to the week holding ``now + AHEAD``: the workers may stop for this long before new
positions land in the default partition."""
UPKEEP_LOCK = 0x64726D70  # "drmp": the advisory lock key of the partition upkeep
LOCK_TIMEOUT = "5s"
"""How long the upkeep waits for a table lock (a long query on the positions); it gives up and retries on the
next pass rather than queue live inserts behind it."""
COMPACTED = "driftmap: thinned and compacted"
_NAME = re.compile(rf"^{PARENT}_w(\d{{8}})$")


@dataclass(frozen=True)
class Upkeep:
    """What one :func:`upkeep` did: partition names created and dropped; ``locked`` False when another
    worker held the upkeep lock and nothing was done."""

    created: tuple[str, ...]
    dropped: tuple[str, ...]
    locked: bool = True


def week_start(moment: datetime) -> datetime:
    """The Monday 00:00 UTC on or before ``moment`` (timezone-aware)."""
    day = moment.astimezone(UTC).replace(hour=0, minute=0, second=0, microsecond=0)
    return day - timedelta(days=day.weekday())


def partition_name(start: datetime) -> str:
    """Name of the weekly partition that starts at ``start`` (a :func:`week_start`)."""
    return f"{PARENT}_w{start.astimezone(UTC):%Y%m%d}"


def is_partition_name(name: str) -> bool:
    """Whether table ``name`` is one of the positions' partitions (schema comparisons leave them out)."""
    return name == DEFAULT_PARTITION or _NAME.match(name) is not None


def is_partitioned(connection: Connection) -> bool:
    """Whether ``vehicle_positions`` is a partitioned table (PostgreSQL after migration 0018)."""
    if connection.dialect.name != "postgresql":
        return False
    found = connection.execute(
        text("SELECT 1 FROM pg_partitioned_table WHERE partrelid = to_regclass(:parent)"), {"parent": PARENT}
    ).first()
    return found is not None


def partitions(connection: Connection) -> dict[str, datetime]:
    """The weekly partitions attached to ``vehicle_positions``: name -> start (UTC), oldest first."""
    names = connection.scalars(
        text(
            "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid "
            "WHERE i.inhparent = to_regclass(:parent)"
        ),
        {"parent": PARENT},
    ).all()
    starts = {}
    for name in names:
        match = _NAME.match(name)
        if match:
            starts[name] = datetime.strptime(match.group(1), "%Y%m%d").replace(tzinfo=UTC)
    return dict(sorted(starts.items(), key=lambda item: item[1]))


def upkeep(connection: Connection, now: datetime, drop_before: datetime | None) -> Upkeep:
    """Create the weekly partitions from ``now``'s week to ``now + AHEAD``'s, and drop every weekly partition
    that ends at or before ``drop_before`` (None: drop none). The caller commits; a partitioned table only."""
    if not connection.scalar(text("SELECT pg_try_advisory_xact_lock(:key)"), {"key": UPKEEP_LOCK}):
        return Upkeep((), (), locked=False)
    connection.execute(text(f"SET LOCAL lock_timeout = '{LOCK_TIMEOUT}'"))
    existing = partitions(connection)
    created = []
    start = week_start(now)
    while start <= now + AHEAD:
        name = partition_name(start)
        if name not in existing:
            _create(connection, name, start)
            created.append(name)
        start += WEEK
    dropped = []
    if drop_before is not None:
        for name, begins in existing.items():
            if begins + WEEK <= drop_before:
                connection.execute(text(f'DROP TABLE "{name}"'))
                dropped.append(name)
    return Upkeep(tuple(created), tuple(dropped))


def compact(connection: Connection, thinned_before: datetime, drop_before: datetime | None) -> str | None:
    """Rewrite the oldest weekly partition that ends at or before ``thinned_before`` (its rows all thinned),
    is not compacted yet and is not due to be dropped (ends after ``drop_before``); returns its name, or None
    when there is none or another worker holds the upkeep lock. The caller commits."""
    if not connection.scalar(text("SELECT pg_try_advisory_xact_lock(:key)"), {"key": UPKEEP_LOCK}):
        return None
    connection.execute(text(f"SET LOCAL lock_timeout = '{LOCK_TIMEOUT}'"))
    comments: dict[str, str | None] = dict(
        connection.execute(
            text(
                "SELECT c.relname, obj_description(c.oid, 'pg_class') FROM pg_inherits i "
                "JOIN pg_class c ON c.oid = i.inhrelid WHERE i.inhparent = to_regclass(:parent)"
            ),
            {"parent": PARENT},
        ).all()
    )
    for name, start in partitions(connection).items():
        end = start + WEEK
        due = end <= thinned_before and (drop_before is None or end > drop_before)
        if due and comments.get(name) != COMPACTED:
            _rewrite(connection, name, start)
            return name
    return None


def _rewrite(connection: Connection, name: str, start: datetime) -> None:
    """Replace weekly partition ``name`` by a compact copy of its rows (see the module doc)."""
    new, lower, upper = f"{name}_compact", _literal(start), _literal(start + WEEK)
    connection.execute(text(f'LOCK TABLE "{name}" IN SHARE MODE'))  # no row changes while it is copied
    connection.execute(text(f'CREATE TABLE "{new}" (LIKE {PARENT} INCLUDING ALL)'))
    connection.execute(text(f'INSERT INTO "{new}" SELECT * FROM "{name}"'))
    foreign_keys = connection.execute(
        text(
            "SELECT conname, pg_get_constraintdef(oid) FROM pg_constraint "
            "WHERE conrelid = to_regclass(:parent) AND contype = 'f'"
        ),
        {"parent": PARENT},
    ).all()
    for constraint, definition in foreign_keys:
        connection.execute(text(f'ALTER TABLE "{new}" ADD CONSTRAINT "{constraint}" {definition}'))
    connection.execute(
        text(
            f'ALTER TABLE "{new}" ADD CONSTRAINT "{new}_week" '
            f"CHECK (received_at >= {lower} AND received_at < {upper})"
        )
    )  # lets the attach skip scanning the rows
    connection.execute(text(f'ALTER TABLE {PARENT} DETACH PARTITION "{name}"'))
    connection.execute(
        text(f'ALTER TABLE {PARENT} ATTACH PARTITION "{new}" FOR VALUES FROM ({lower}) TO ({upper})')
    )
    connection.execute(text(f'DROP TABLE "{name}"'))
    connection.execute(text(f'ALTER TABLE "{new}" RENAME TO "{name}"'))
    connection.execute(text(f"COMMENT ON TABLE \"{name}\" IS '{COMPACTED}'"))


def _create(connection: Connection, name: str, start: datetime) -> None:
    """Create and attach the weekly partition ``name`` starting at ``start``, moving its rows out of the
    default partition."""
    lower, upper = _literal(start), _literal(start + WEEK)
    connection.execute(
        text(f'CREATE TABLE "{name}" (LIKE {PARENT} INCLUDING DEFAULTS INCLUDING CONSTRAINTS)')
    )
    connection.execute(
        text(
            f"WITH moved AS (DELETE FROM {DEFAULT_PARTITION} WHERE received_at >= {lower} "
            f'AND received_at < {upper} RETURNING *) INSERT INTO "{name}" SELECT * FROM moved'
        )
    )
    connection.execute(
        text(f'ALTER TABLE {PARENT} ATTACH PARTITION "{name}" FOR VALUES FROM ({lower}) TO ({upper})')
    )


def _literal(moment: datetime) -> str:
    """A UTC moment as a PostgreSQL ``timestamptz`` literal (partition bounds cannot be bound parameters)."""
    return f"'{moment.astimezone(UTC):%Y-%m-%d %H:%M:%S}+00'::timestamptz"
