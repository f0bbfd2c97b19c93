"""Localiser worker processes: a database error inside one reaches the server as a readable error. (That
they end with the server: ``tests/test_processes.py``.)"""

from __future__ import annotations

import asyncio
import pickle
import time
from pathlib import Path

import pytest
from sqlalchemy import text

from driftmap.config import Settings
from driftmap.live.workers import LiveDatabaseError, LocaliserWorkers
from driftmap.services import vehicles as vehicle_service
from driftmap.store.storage import Storage
from tests.api.access_helpers import built_tiny_data, copy_data, localisation_drive, recorded_frames

pytestmark = pytest.mark.db  # the workers open the database


def test_a_database_error_in_a_worker_reaches_the_server_as_text(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path
) -> None:
    data = copy_data(built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data")
    settings = Settings(data_dir=data)
    storage = Storage.open(settings)
    with storage.db.session() as session:
        vehicle, _token = vehicle_service.create_vehicle(session, "lhd", 1)
    with storage.db.engine.begin() as connection:  # the write of every estimate now fails
        connection.execute(text("DROP TABLE vehicle_positions"))
    storage.close()
    frame = recorded_frames(localisation_drive(tiny_site_dir), 1)[0]
    workers = LocaliserWorkers(settings, processes=1)
    try:
        with pytest.raises(LiveDatabaseError, match="vehicle_positions") as raised:
            asyncio.run(workers.localise(vehicle.id, frame.t, frame.data, (0, 0)))
    finally:
        workers.close()
    assert pickle.loads(pickle.dumps(raised.value)).args == raised.value.args


class TestSharing:
    """Frames go to any free process (not ``vehicle_id % processes``), longest-waiting vehicle first."""

    WORK_S = 0.4  # what each call does in a worker process: sleep, seconds

    def test_vehicles_with_the_same_remainder_run_side_by_side(self, settings: Settings) -> None:
        Storage.open(settings).close()  # the database the workers open
        workers = LocaliserWorkers(settings, processes=2)

        async def run() -> float:
            await workers.start()
            start = time.monotonic()
            await asyncio.gather(*(workers._run(v, time.sleep, self.WORK_S) for v in (1, 3)))
            return time.monotonic() - start

        try:
            took = asyncio.run(run())
        finally:
            workers.close()
        assert took < 1.5 * self.WORK_S  # pinned to process 1 both, they took 2 x WORK_S

    def test_a_freed_process_goes_to_the_longest_waiting_vehicle(self, settings: Settings) -> None:
        workers = LocaliserWorkers(settings, processes=1)  # the queue only: no process is started

        async def run() -> list[int]:
            order: list[int] = []
            held = await workers._acquire(1)

            async def wait(vehicle_id: int) -> None:
                index = await workers._acquire(vehicle_id)
                order.append(vehicle_id)
                workers._release(index)

            waiting = []
            for vehicle_id in (2, 3, 1):
                waiting.append(asyncio.create_task(wait(vehicle_id)))
                await asyncio.sleep(0)  # each joins the queue in turn
            workers._release(held)
            await asyncio.gather(*waiting)
            return order

        assert asyncio.run(run()) == [2, 3, 1]
        assert workers._busy == [False]
