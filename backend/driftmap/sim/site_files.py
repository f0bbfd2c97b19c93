"""The files of a simulated site: its drive folders (with obscured copies) and ``site.json``."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.drive_json import camera_to_json
from driftmap.formats.records import DriveMeta, FrameRow, GroundingRow
from driftmap.sim.motion import DrivePlan
from driftmap.sim.trajectory import FramePoses

__all__ = ["SITE_FORMAT", "DriveSummary", "write_drive", "write_site_json"]

log = logging.getLogger(__name__)

SITE_FORMAT = "driftmap-sim-site/1"


@dataclass(frozen=True)
class DriveSummary:
    """One written drive folder."""

    name: str
    kind: str  # "mapping" or "localisation"
    frames: int
    duration_s: float
    groundings: int
    source: str | None = None  # for an obscured copy: the drive it copies
    obscurant: str | None = None  # "dust1", "dust2", "water1" or "water2"


def _frame_rows(poses: FramePoses) -> list[FrameRow]:
    return [
        FrameRow(i, round(float(t), 4), round(float(x), 4), round(float(y), 4), round(float(a), 6))
        for i, (t, (x, y), a) in enumerate(zip(poses.t, poses.xy, poses.yaw, strict=True))
    ]


def write_drive(
    out_dir: Path, plan: DrivePlan, poses: FramePoses, camera: Any, fps: float, images: dict[str, list[bytes]]
) -> list[DriveSummary]:
    """Write drive ``plan``'s folder and one per obscured variant of ``images`` (key "" is the clean drive)."""
    rows = _frame_rows(poses)
    ground = [GroundingRow(f, round(x, 3), round(y, 3)) for f, x, y in poses.groundings]
    kind = plan.kind
    out = []
    for variant, data in images.items():
        name = plan.name if variant == "" else f"{plan.name}-{variant}"
        meta = DriveMeta(name=name, kind=kind, fps=fps, camera=camera)
        g = ground if kind == "mapping" else None
        write_drive_folder(out_dir / "drives" / name, meta, rows, data, g)
        out.append(
            DriveSummary(
                name,
                kind,
                len(rows),
                round(float(poses.t[-1]), 3),
                len(g or []),
                plan.name if variant else None,
                variant or None,
            )
        )
    log.info("wrote drive %s (%d frames)", plan.name, len(rows))
    return out


def write_site_json(
    out_dir: Path,
    seed: int,
    size: str,
    camera_name: str,
    layout: Any,
    camera: Any,
    fps: float,
    drives: list[DriveSummary],
) -> None:
    """Write ``site.json``: seed, size, camera, tunnel graph and the drives written."""
    doc = {
        "format": SITE_FORMAT,
        "seed": seed,
        "size": size,
        "camera_name": camera_name,
        "tunnel_length_m": round(layout.total_length_m, 2),
        "tunnel_height_m": layout.height_m,
        "fps": fps,
        "camera": camera_to_json(camera),
        "nodes": [
            {"id": n.id, "name": n.name, "kind": n.kind, "x": round(n.xy[0], 3), "y": round(n.xy[1], 3)}
            for n in layout.nodes
        ],
        "edges": [
            {
                "id": e.id,
                "a": e.a,
                "b": e.b,
                "kind": e.kind,
                "width_m": e.width_m,
                "length_m": round(e.length_m, 2),
            }
            for e in layout.edges
        ],
        "drives": [
            {
                "name": d.name,
                "kind": d.kind,
                "frames": d.frames,
                "duration_s": d.duration_s,
                "groundings": d.groundings,
                "source": d.source,
                "obscurant": d.obscurant,
            }
            for d in drives
        ],
    }
    (out_dir / "site.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
