"""Replay recorded drives as live vehicles through a running server's HTTP API.

Each drive folder becomes a vehicle named after the folder (created through ``POST /api/vehicles`` or
reused, with a fresh token from ``POST /api/vehicles/{id}/token``), and its frames are posted to
``POST /api/vehicles/{id}/frames?t=`` at the pace of their ``frames.csv`` timestamps, as a camera would
deliver them: when a vehicle falls behind (the server answered late) it drops the frames whose time has
passed instead of piling them up, and counts them. ``t`` is the wall clock (Unix seconds) at sending, so it
keeps increasing across loops and across runs and position histories read as clock time.

Only the standard library talks HTTP here (``urllib``), so the command needs nothing beyond the runtime
install. One thread per vehicle; every wait watches a stop event, so Ctrl-C ends a replay within a frame.
"""

from __future__ import annotations

import json
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from driftmap.errors import BadInputError, ConflictError, DriftmapError, NotFoundError
from driftmap.formats.drive_folder import read_drive_folder
from driftmap.formats.drive_json import camera_to_json

CONTENT_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}


class ApiError(DriftmapError):
    """The server answered an error (or could not be reached)."""


class ApiClient:
    """A small JSON client of the driftmap API.

    Args:
        base_url: e.g. ``http://127.0.0.1:8000`` (no trailing ``/api``).
        token: bearer token sent with every request, when set.
        timeout_s: per-request timeout, seconds.
    """

    def __init__(self, base_url: str, token: str | None = None, timeout_s: float = 30.0) -> None:
        self.base_url = base_url.rstrip("/")
        self.token = token
        self.timeout_s = timeout_s

    def request(
        self,
        method: str,
        path: str,
        body: object | None = None,
        *,
        data: bytes | None = None,
        content_type: str | None = None,
        token: str | None = None,
    ) -> Any:
        """Call ``method path`` with a JSON ``body`` or raw ``data``; returns the decoded JSON answer."""
        headers = {"Accept": "application/json"}
        bearer = token or self.token
        if bearer:
            headers["Authorization"] = f"Bearer {bearer}"
        if body is not None:
            data, content_type = json.dumps(body).encode(), "application/json"
        if content_type:
            headers["Content-Type"] = content_type
        request = urllib.request.Request(self.base_url + path, data=data, headers=headers, method=method)
        try:
            with urllib.request.urlopen(request, timeout=self.timeout_s) as response:
                raw = response.read()
        except urllib.error.HTTPError as exc:
            detail = exc.read().decode(errors="replace")[:300]
            raise ApiError(f"{method} {path}: HTTP {exc.code} {detail}") from None
        except (urllib.error.URLError, OSError) as exc:
            raise ApiError(f"{method} {path}: {exc}") from None
        return json.loads(raw) if raw else None

    def login(self, username: str, password: str) -> None:
        """Log in as a user; later requests carry its token."""
        answer = self.request("POST", "/api/auth/login", {"username": username, "password": password})
        self.token = str(answer["access_token"])

    def healthy(self) -> bool:
        """Whether ``/api/health`` answers."""
        try:
            self.request("GET", "/api/health")
        except ApiError:
            return False
        return True


def wait_until_healthy(client: ApiClient, deadline_s: float, alive: Callable[[], bool]) -> None:
    """Poll ``/api/health`` until it answers; ConflictError after ``deadline_s`` or when ``alive()`` fails."""
    until = time.monotonic() + deadline_s
    while not client.healthy():
        if not alive():
            raise ConflictError("the server process ended before it answered /api/health")
        if time.monotonic() > until:
            raise ConflictError(f"no answer from {client.base_url}/api/health within {deadline_s:.0f} s")
        time.sleep(0.3)


@dataclass(frozen=True)
class RecordedDrive:
    """The frames of one drive folder: recorded times (s, from 0) and image files, in time order, and its
    camera block (drive.json's ``camera``), which the replayed vehicle is given for its odometry."""

    name: str
    times_s: tuple[float, ...]
    files: tuple[Path, ...]
    camera: dict[str, Any] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """From the first to the last frame, seconds."""
        return self.times_s[-1] - self.times_s[0]


def load_drive(path: Path) -> RecordedDrive:
    """Read a drive folder's frame list (BadInputError when it breaks the format or has no frame)."""
    folder = read_drive_folder(path)
    if not folder.frames:
        raise BadInputError("the drive has no frame", file=path / "frames.csv")
    t0 = folder.frames[0].t_s
    return RecordedDrive(
        path.name,
        tuple(r.t_s - t0 for r in folder.frames),
        tuple(folder.frame_files),
        camera_to_json(folder.meta.camera),
    )


def site_id_by_name(client: ApiClient, name: str) -> int:
    """The id of the site called ``name`` (NotFoundError when there is none)."""
    page = client.request("GET", "/api/sites?limit=500")
    for site in page["items"]:
        if site["name"] == name:
            return int(site["id"])
    raise NotFoundError(f"no site called {name!r} on {client.base_url}")


def vehicle_with_token(
    client: ApiClient, site_id: int, name: str, camera: dict[str, Any] | None = None
) -> tuple[int, str]:
    """The vehicle ``name`` of the site (created when missing) and a fresh token for it (admin); with
    ``camera`` (a drive.json camera block) the vehicle is given that camera, so it is localised with
    odometry."""
    vehicle_id = None
    for vehicle in client.request("GET", f"/api/vehicles?site_id={site_id}"):
        if vehicle["name"] == name:
            rotated = client.request("POST", f"/api/vehicles/{vehicle['id']}/token")
            vehicle_id, token = int(rotated["id"]), str(rotated["token"])
    if vehicle_id is None:
        created = client.request("POST", "/api/vehicles", {"name": name, "site_id": site_id})
        vehicle_id, token = int(created["id"]), str(created["token"])
    if camera:
        client.request("PUT", f"/api/vehicles/{vehicle_id}/camera", camera)
    return vehicle_id, token


@dataclass
class ReplayStats:
    """What one vehicle's replay did so far (updated by its thread)."""

    vehicle: str
    vehicle_id: int
    sent: int = 0
    processed: int = 0
    skipped: int = 0
    """Answered ``skipped`` or ``out_of_order`` by the server."""
    late: int = 0
    """Not sent: their time had passed when the vehicle was ready (it was waiting for the server)."""
    errors: int = 0
    loops: int = 0
    last: dict[str, Any] = field(default_factory=dict)
    """The last estimate the server answered."""
    error: str | None = None
    """The last error, when any."""


def replay_vehicle(
    client: ApiClient,
    stats: ReplayStats,
    token: str,
    drive: RecordedDrive,
    stop: threading.Event,
    *,
    loop: bool = True,
    max_frames: int | None = None,
    speed: float = 1.0,
) -> None:
    """Post a drive's frames as vehicle ``stats.vehicle_id`` at their recorded pace until done or stopped.

    Args:
        client: the API client (its base URL; the vehicle's ``token`` is sent instead of its own).
        stats: updated in place as frames are answered.
        token: the vehicle's API token.
        drive: the recorded frames.
        stop: set to end the replay (checked before every frame and during every wait).
        loop: start the drive again after its last frame (until stopped), else end after one pass.
        max_frames: end after sending this many frames (None: no limit).
        speed: time-lapse factor (2 plays twice as fast).
    """
    path = f"/api/vehicles/{stats.vehicle_id}/frames"
    gap_s = drive.duration_s / max(len(drive.times_s) - 1, 1) + 1.0  # pause between two loops, seconds
    start = time.monotonic()
    offset_s = 0.0
    last_t = 0.0
    while not stop.is_set():
        for i, (rel_s, file) in enumerate(zip(drive.times_s, drive.files, strict=True)):
            due = start + (offset_s + rel_s) / speed
            next_due = (
                start + (offset_s + drive.times_s[i + 1]) / speed if i + 1 < len(drive.times_s) else None
            )
            if next_due is not None and time.monotonic() >= next_due:
                stats.late += 1  # the next frame is already due: this one is history
                continue
            if stop.wait(max(due - time.monotonic(), 0.0)):
                return
            last_t = max(time.time(), last_t + 1e-3)
            content_type = CONTENT_TYPES.get(file.suffix.lower(), "application/octet-stream")
            try:
                answer = client.request(
                    "POST",
                    f"{path}?t={last_t:.3f}",
                    data=file.read_bytes(),
                    content_type=content_type,
                    token=token,
                )
            except (ApiError, OSError) as exc:
                stats.errors += 1
                stats.error = str(exc)
                if stop.wait(1.0):  # the server may be restarting: do not spin
                    return
                continue
            finally:
                stats.sent += 1
            if answer.get("status") == "processed":
                stats.processed += 1
                stats.last = answer
            else:
                stats.skipped += 1
            if max_frames is not None and stats.sent >= max_frames:
                return
        stats.loops += 1
        if not loop:
            return
        offset_s += drive.duration_s + gap_s


def describe(stats: ReplayStats) -> str:
    """One status line of a vehicle's replay."""
    last = stats.last
    where = (
        f"at ({last['x']:.1f}, {last['y']:.1f}) node {last['node']} conf {last['confidence']:.2f}"
        f"{' LOST' if last.get('lost') else ''}"
        if last.get("x") is not None
        else "no estimate yet"
    )
    errors = f", {stats.errors} errors (last: {stats.error})" if stats.errors else ""
    return (
        f"{stats.vehicle} (vehicle {stats.vehicle_id}): {stats.sent} sent, {stats.processed} localised, "
        f"{stats.skipped} skipped, {stats.late} late; {where}{errors}"
    )
