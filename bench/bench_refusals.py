"""How fast, and with how much memory, a real server refuses the attacks of issue 25.

Starts ``driftmap serve --no-worker`` on a new data dir (one site with a small plan, a vehicle with a 320x240
camera, an empty drive) and sends each hostile request once, as the issue found them: image bombs to the live
and drive frame routes, an absurd camera block, integers past 2^63, non-finite times, a lone surrogate, a DXF
plan of one CIRCLE of radius 1e12, a 30 MB plan of 1.2 million vertices, a 20 MB JSON body, a vehicle token
with a huge id, 200 concurrent wrong logins (and the health probe meanwhile). While each request runs, a
thread samples the resident memory of the server's process tree every 5 ms.

Prints, per attack: the status answered, the wall time until the answer, and the extra resident memory of
the server at its peak over its level just before. The baseline is a plain ``GET /api/health`` timed the same
way. Target (issue 25): every attack refused in under 1 s with under 100 MB of extra memory.

Usage: ``.venv/bin/python bench/bench_refusals.py``
"""

from __future__ import annotations

import io
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import ezdxf
import httpx

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' image bombs

from tests.image_bombs import zero_png

from bench_live import serving
from driftmap.config import Settings
from driftmap.services import sites as site_service
from driftmap.services import users as user_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.storage import Storage
from proc_tree import tree_rss_mb

CAMERA = {
    "width": 320, "height": 240, "ground_roi": [80, 150, 160, 80], "k_x": 0.01, "k_y": 0.01,
    "y_c": 1.0, "y_h": 120.0, "forward_sign": 1,
}  # fmt: skip
HUGE = "9" * 20  # past 2^63 - 1
CIRCLE_1E12 = (
    b"  0\nSECTION\n  2\nENTITIES\n  0\nCIRCLE\n  5\n2A\n  8\nWALLS\n 10\n0.0\n 20\n0.0\n 30\n0.0\n"
    b" 40\n1000000000000.0\n  0\nENDSEC\n  0\nEOF\n"
)
TARGET_S, TARGET_MB = 1.0, 100.0


def small_plan() -> bytes:
    doc = ezdxf.new("R2000")
    doc.modelspace().add_lwpolyline([(0, 0), (100, 0), (100, 5), (0, 5)], dxfattribs={"layer": "WALLS"})
    out = io.StringIO()
    doc.write(out)
    return out.getvalue().encode()


def many_vertices_plan(polylines: int = 12_000, vertices: int = 100) -> bytes:
    """An ASCII DXF of ``polylines`` LWPOLYLINEs of ``vertices`` each (1.2 million vertices, about 30 MB)."""
    rows = [b"  0\nSECTION\n  2\nENTITIES\n"]
    for k in range(polylines):
        body = b"".join(b" 10\n%d.0\n 20\n%d.0\n" % (i, k) for i in range(vertices))
        rows.append(b"  0\nLWPOLYLINE\n  8\nWALLS\n 90\n%d\n 70\n0\n" % vertices + body)
    rows.append(b"  0\nENDSEC\n  0\nEOF\n")
    return b"".join(rows)


def prepare(data: Path) -> dict[str, str]:
    """A data dir with an admin, a site with a plan, a vehicle with a camera; returns the vehicle's token."""
    storage = Storage.open(Settings(data_dir=data))
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.create_site(session, "bench")
        site_service.add_survey_map(session, batch, site, small_plan(), "plan.dxf")
        user_service.create_user(session, "bench", "bench-password", "admin")
        vehicle, token = vehicle_service.create_vehicle(session, "v1", site.id)
        vehicle_service.set_camera(session, vehicle, CAMERA)
        ids = {"site": str(site.id), "vehicle": str(vehicle.id), "vehicle_token": token}
    storage.close()
    return ids


class PeakSampler:
    """Samples the RSS of a process tree every 5 ms in a thread; ``peak_mb`` is the highest total seen."""

    def __init__(self, root: int) -> None:
        self.root, self.peak_mb, self._stop = root, 0.0, threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            self.peak_mb = max(self.peak_mb, sum(tree_rss_mb(self.root).values()))
            time.sleep(0.005)

    def __enter__(self) -> PeakSampler:
        self._thread.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self._stop.set()
        self._thread.join()


def measure(pid: int, send: Callable[[], int]) -> tuple[int, float, float]:
    """(status, seconds, extra MB at the peak) of one request sent by ``send``."""
    before = sum(tree_rss_mb(pid).values())
    with PeakSampler(pid) as sampler:
        start = time.perf_counter()
        status = send()
        seconds = time.perf_counter() - start
    return status, seconds, max(sampler.peak_mb - before, 0.0)


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="driftmap-bench-refusals-") as tmp:
        ids = prepare(Path(tmp) / "data")
        with serving(Path(tmp) / "data", Path(tmp), "--no-worker") as (base, pid):
            client = httpx.Client(base_url=base, timeout=600.0)
            login = client.post("/api/auth/login", json={"username": "bench", "password": "bench-password"})
            admin = {"Authorization": f"Bearer {login.json()['access_token']}"}
            vehicle = {"Authorization": f"Bearer {ids['vehicle_token']}", "Content-Type": "image/png"}
            drive = client.post(
                f"/api/sites/{ids['site']}/drives",
                json={"name": "rec", "kind": "localisation", "fps": 10.0, "camera": CAMERA},
                headers=admin,
            ).json()["id"]
            bomb, plan = zero_png(30_000, 30_000), many_vertices_plan()
            frames_url, drive_frames = f"/api/vehicles/{ids['vehicle']}/frames", f"/api/drives/{drive}/frames"

            def post(url: str, **kwargs: object) -> Callable[[], int]:
                return lambda: client.post(url, **kwargs).status_code  # type: ignore[arg-type]

            def logins() -> int:
                wrong = {"username": "bench", "password": "wrong-password"}

                def one() -> tuple[int, float]:
                    start = time.perf_counter()
                    return client.post("/api/auth/login", json=wrong).status_code, time.perf_counter() - start

                with ThreadPoolExecutor(50) as pool:
                    futures = [pool.submit(one) for _ in range(200)]
                    start = time.perf_counter()
                    probe = client.get("/api/health").status_code
                    probe_s = time.perf_counter() - start
                    answers = [f.result() for f in futures]
                times = sorted(s for _c, s in answers)
                print(
                    f"  (each login answered in {statistics.median(times):.3f} s median, {times[-1]:.3f} s at most; "
                    f"{sorted({c for c, _s in answers})}; /api/health meanwhile {probe} in {probe_s:.3f} s)"
                )
                return max(c for c, _s in answers)

            attacks: dict[str, Callable[[], int]] = {
                "live frame: 30,000 x 30,000 PNG bomb (0.9 MB)": post(
                    frames_url, params={"t": 1.0}, content=bomb, headers=vehicle
                ),
                "drive frame: the same bomb": post(
                    drive_frames,
                    params={"t": 0.0},
                    content=bomb,
                    headers={**admin, "Content-Type": "image/png"},
                ),
                "camera block 100,000 x 100,000": lambda: (
                    client.put(
                        f"/api/vehicles/{ids['vehicle']}/camera",
                        json={**CAMERA, "width": 100_000, "height": 100_000},
                        headers=admin,
                    ).status_code
                ),
                "an id past 2^63 in the path": lambda: (
                    client.get(f"/api/sites/{HUGE}", headers=admin).status_code
                ),
                "a vehicle token with such an id": post(
                    frames_url,
                    params={"t": 2.0},
                    content=b"x",
                    headers={"Authorization": f"Bearer dmv_{HUGE}_x"},
                ),
                "live frame t=1e308": post(frames_url, params={"t": "1e308"}, content=b"x", headers=vehicle),
                "drive frame t=nan": post(
                    drive_frames,
                    params={"t": "nan"},
                    content=b"x",
                    headers={**admin, "Content-Type": "image/png"},
                ),
                "a lone surrogate in JSON": post(
                    "/api/sites",
                    content=b'{"name": "\\ud800"}',
                    headers={**admin, "Content-Type": "application/json"},
                ),
                "DXF: one CIRCLE of radius 1e12 (152 bytes)": post(
                    f"/api/sites/{ids['site']}/survey",
                    files={"file": ("plan.dxf", CIRCLE_1E12)},
                    headers=admin,
                ),
                f"DXF: 1.2 million vertices ({len(plan) / 1e6:.0f} MB)": post(
                    f"/api/sites/{ids['site']}/survey", files={"file": ("big.dxf", plan)}, headers=admin
                ),
                "JSON body of 20 MB": post(
                    "/api/sites",
                    content=b'{"name": "x", "description": "' + b"a" * 20_000_000 + b'"}',
                    headers={**admin, "Content-Type": "application/json"},
                ),
                "200 concurrent wrong logins": logins,
            }
            health = [measure(pid, lambda: client.get("/api/health").status_code)[1] for _ in range(20)]
            print(f"baseline GET /api/health: {statistics.median(health) * 1e3:.1f} ms median")
            print(f"{'attack':52} {'status':>6} {'seconds':>8} {'extra MB':>9}")
            worst_s = worst_mb = 0.0
            for name, send in attacks.items():
                status, seconds, extra = measure(pid, send)
                worst_s, worst_mb = max(worst_s, seconds), max(worst_mb, extra)
                print(f"{name:52} {status:>6} {seconds:>8.3f} {extra:>9.1f}")
            print(
                f"slowest refusal {worst_s:.2f} s ({worst_s / statistics.median(health):.0f}x a health check), "
                f"most extra memory {worst_mb:.0f} MB (target < {TARGET_S:g} s and < {TARGET_MB:g} MB)"
            )


if __name__ == "__main__":
    main()
