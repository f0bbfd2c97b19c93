"""Plain records of one drive as the drive-folder format carries it (``docs/formats.md``).

These are what the readers return and the writers take; the store and the simulator use them too.
Units: seconds, metres, radians; positions in the survey frame (x east, y north).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from driftmap.core.odometry.camera import CameraModel

DRIVE_FORMAT = "driftmap-drive/1"
DRIVE_FORMAT_LENS = "driftmap-drive/2"  # written when the camera block carries a lens
DRIVE_FORMATS: tuple[str, ...] = (DRIVE_FORMAT, DRIVE_FORMAT_LENS)
DriveKind = Literal["mapping", "localisation"]
DRIVE_KINDS: tuple[str, ...] = ("mapping", "localisation")


STATION_MAX_CHARS = 64
"""The longest survey station id stored, characters."""


@dataclass(frozen=True)
class DriveMeta:
    """The contents of ``drive.json``."""

    name: str
    kind: DriveKind
    fps: float
    camera: CameraModel


@dataclass(frozen=True)
class FrameRow:
    """One row of ``frames.csv``: frame number, time and optional ground truth.

    ``x_m, y_m`` is the floor point under the camera and ``yaw_rad`` the vehicle heading, counter-
    clockwise from +x; all three are None when the drive has no ground truth.
    """

    frame: int
    t_s: float
    x_m: float | None = None
    y_m: float | None = None
    yaw_rad: float | None = None

    @property
    def has_truth(self) -> bool:
        return self.x_m is not None and self.y_m is not None and self.yaw_rad is not None


@dataclass(frozen=True)
class GroundingRow:
    """One row of ``groundings.csv``: this frame was taken at this surveyed point (metres)."""

    frame: int
    x_m: float
    y_m: float
    station: str | None = None
    """The survey station's id (e.g. ``STN-104``), when the point is one."""
    enabled: bool = True
    """Whether map builds use the grounding."""


@dataclass(frozen=True)
class SiteGroundingRow:
    """One row of a site's survey control file: a mapping drive's frame grounded at a surveyed point."""

    drive: str
    frame: int
    station: str | None
    x_m: float
    y_m: float
    """Surveyed position, metres (survey frame: x east, y north)."""
    enabled: bool
