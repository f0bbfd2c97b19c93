"""Benchmark: importing a drive of 320x240 PNG frames into SQLite + the blob store.

Target (issue 2): at least 300 frames/s. Baseline, run in the same process on the same files: a plain
copy of the drive folder (read every file, write it elsewhere), i.e. the cost of the bytes alone.
Prints medians over several runs and the ratio import/copy.
"""

from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.drive_factory import CAMERA

from driftmap.config import Settings
from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.records import DriveMeta, FrameRow
from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.store.storage import Storage

FRAMES = 1000
RUNS = 5


def tunnel_like_frames(count: int, seed: int = 0) -> list[bytes]:
    """PNG frames of smooth random texture (compresses like rendered frames, not like white noise)."""
    rng = np.random.default_rng(seed)
    base = cv2.GaussianBlur(rng.normal(128, 40, (480, 640)).astype(np.float32), (0, 0), 2.0)
    frames = []
    for i in range(count):
        shift = i % 160
        tile = base[shift : shift + 240, shift : shift + 320] + rng.normal(0, 3, (240, 320))
        ok, data = cv2.imencode(".png", np.clip(tile, 0, 255).astype(np.uint8))
        assert ok
        frames.append(data.tobytes())
    return frames


def main() -> None:
    work = Path(tempfile.mkdtemp(prefix="driftmap-bench-"))
    try:
        camera = replace(CAMERA, width_px=320, height_px=240, ground_roi_px=(80, 140, 160, 90))
        meta = DriveMeta(name="bench", kind="mapping", fps=10.0, camera=camera)
        rows = [FrameRow(frame=i, t_s=i / 10.0, x_m=float(i), y_m=0.0, yaw_rad=0.0) for i in range(FRAMES)]
        images = tunnel_like_frames(FRAMES)
        source = work / "drive"
        write_drive_folder(source, meta, rows, images)
        mean_kib = sum(len(b) for b in images) / len(images) / 1024
        print(f"drive: {FRAMES} frames of 320x240 PNG, {mean_kib:.0f} KiB each on average")
        import_rates, copy_rates = [], []
        for run in range(RUNS):
            storage = Storage.open(Settings(data_dir=work / f"data-{run}"))
            with storage.db.session() as session:
                site_service.create_site(session, "bench")
            start = time.perf_counter()
            with storage.blobs.batch() as batch, storage.db.session() as session:
                drive_service.import_drive(session, batch, site_service.get_site(session, "bench"), source)
            import_rates.append(FRAMES / (time.perf_counter() - start))
            storage.close()
            start = time.perf_counter()
            shutil.copytree(source, work / f"copy-{run}")
            copy_rates.append(FRAMES / (time.perf_counter() - start))
        imp, cp = statistics.median(import_rates), statistics.median(copy_rates)
        print(f"import into SQLite + blob store: median {imp:,.0f} frames/s over {RUNS} runs (target >= 300)")
        print(f"baseline plain folder copy:      median {cp:,.0f} frames/s")
        print(f"ratio import/copy: {imp / cp:.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
