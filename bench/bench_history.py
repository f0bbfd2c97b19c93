"""Benchmark: position history storage per vehicle-day, the cost of a retention pass, history query time.

Embedded SQLite (the default): stores ``--hours`` of one vehicle's positions at 10 per second as the live path writes them (one row per
processed frame, every column filled), measures the database file's growth per row and extrapolates to a
vehicle-day at full rate and after thinning to one per 10 s (the default retention). Then ages those rows past
``DRIFTMAP_HISTORY_FULL_DAYS`` and times one retention pass (:func:`driftmap.services.retention.apply_retention`),
against the baseline of writing the rows in this process.

``--database postgresql``: on a private PostgreSQL server, the same history (``--vehicles`` vehicles,
``--hours`` each at 10 per second, the vehicles' hours spread over the last 30 days of ``received_at``) is
copied into the weekly-partitioned positions table (migration 0017) and, in the same run, into the plain table
of the schema before it; prints the bytes per position row (table and indexes), the size of 30 days of 50
vehicles under the default retention, and the median time of a one-hour history query for one vehicle through
:func:`driftmap.services.positions.history` (as the API answers it), partitioned against plain.

Usage: ``.venv/bin/python bench/bench_history.py [--hours 2] [--database postgresql [--vehicles 50]
[--extra-partitions 360]]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

from sqlalchemy import func, select

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from driftmap.config import Settings
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.retention import RetentionPolicy, apply_retention
from driftmap.store.access_models import VehiclePosition
from driftmap.store.storage import Storage

FPS = 10.0
DAY_S = 86_400.0


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--hours", type=float, default=2.0, help="hours of positions per vehicle")
    parser.add_argument("--database", choices=("sqlite", "postgresql"), default="sqlite")
    parser.add_argument("--vehicles", type=int, default=50, help="vehicles (PostgreSQL only)")
    parser.add_argument("--runs", type=int, default=7, help="history queries timed per table (PostgreSQL)")
    parser.add_argument(
        "--extra-partitions", type=int, default=0, help="empty partitions added, then the query timed again"
    )
    args = parser.parse_args()
    if args.database == "postgresql":
        from history_postgres import run_postgresql  # bench/ is the script's folder, first on sys.path

        run_postgresql(args.hours, args.vehicles, args.runs, args.extra_partitions)
    else:
        run_sqlite(args.hours)


def run_sqlite(hours: float) -> None:
    """Storage per vehicle-day and the retention pass on the embedded SQLite database."""
    rows = int(hours * 3600 * FPS)
    policy = RetentionPolicy()
    with tempfile.TemporaryDirectory() as tmp:
        storage = Storage.open(Settings(data_dir=Path(tmp)))
        db_file = Path(tmp) / "driftmap.sqlite3"
        with storage.db.session() as session:
            site = site_service.create_site(session, "bench")
            vehicle, _token = vehicle_service.create_vehicle(session, "loader", site.id)
            vehicle_id = vehicle.id
        empty = db_file.stat().st_size
        start = datetime.now(UTC) - timedelta(days=policy.full_days + 1.0)
        t0 = time.perf_counter()
        batch = 20_000
        for first in range(0, rows, batch):
            with storage.db.session() as session:
                for k in range(first, min(first + batch, rows)):
                    t = k / FPS
                    session.add(
                        VehiclePosition(
                            vehicle_id=vehicle_id, map_version_id=None, t_s=t, node=k % 300,
                            x_m=13_000.0 + 0.3 * (k % 5000), y_m=56_000.0 + 0.1 * (k % 7000),
                            yaw_rad=0.01 * (k % 628), confidence=0.97, matched=True, lost=False,
                            received_at=start + timedelta(seconds=t), obscured=False, obscured_reason=None,
                            salient=0.4, sharpness=0.8, speckle=0.01, flat_area=0.1,
                            speed_mps=3.2, moving=True, odometry=True,
                        )
                    )  # fmt: skip
        write_s = time.perf_counter() - t0
        full = db_file.stat().st_size
        per_row = (full - empty) / rows
        t0 = time.perf_counter()
        with storage.db.session() as session:
            done = apply_retention(session, policy, datetime.now(UTC))
        pass_s = time.perf_counter() - t0
        with storage.db.session() as session:
            left = session.scalar(select(func.count()).select_from(VehiclePosition))
        storage.close()
    day_rows = DAY_S * FPS
    thinned_rows = DAY_S / policy.downsample_s
    print(f"{rows} positions of one vehicle ({hours:g} h at {FPS:g}/s) written in {write_s:.1f} s")
    print(f"SQLite bytes per position row (indexes included): {per_row:.0f}")
    print(
        f"per vehicle-day: full rate {day_rows:,.0f} rows, {day_rows * per_row / 1e6:.0f} MB; "
        f"thinned to one per {policy.downsample_s:g} s {thinned_rows:,.0f} rows, {thinned_rows * per_row / 1e6:.1f} MB"
    )
    print(
        f"retention pass over them: {pass_s:.2f} s, {done.thinned} thinned, {left} left "
        f"(ratio pass / write: {pass_s / write_s:.3f})"
    )


if __name__ == "__main__":
    main()
