"""A cut-down tiny simulated site (the first frames of every drive) for job and API tests, zipped on demand.

The full tiny site takes a minute to simulate and a map build of it tens of seconds on the 2-core machine;
100 frames per drive keep a grounding on each mapping drive and build in a few seconds.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import pytest

from driftmap.sim import simulate_site
from tests.made_once import made_once

MINI_FRAMES = 100
MINI_SEED = 3
_made: dict[str, Path] = {}


def mini_site_dir(factory: pytest.TempPathFactory) -> Path:
    """The mini site, simulated once per test process (read-only for tests)."""
    if "site" not in _made:
        _made["site"] = made_once(
            factory,
            "mini-site",
            lambda out: simulate_site(
                out, seed=MINI_SEED, size="tiny", obscurants=False, max_frames_per_drive=MINI_FRAMES
            ),
        )
    return _made["site"]


def drive_folders(site_dir: Path, prefix: str = "") -> list[Path]:
    """The drive folders of a simulated site whose names start with ``prefix``, sorted."""
    return sorted(p for p in (site_dir / "drives").iterdir() if p.name.startswith(prefix))


def zip_folder(folder: Path, *, top: bool = True, skip: tuple[str, ...] = ()) -> bytes:
    """A zip of ``folder`` (inside a top-level folder of its name when ``top``), leaving out ``skip`` paths."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for file in sorted(folder.rglob("*")):
            inner = file.relative_to(folder).as_posix()
            if file.is_file() and inner not in skip:
                archive.write(file, f"{folder.name}/{inner}" if top else inner)
    return buffer.getvalue()
