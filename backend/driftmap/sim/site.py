"""``simulate_site``: generate, render and write a whole synthetic mine site.

Output layout::

    OUT/survey.dxf            the surveyed map (layers WALLS, CENTRELINE, DRAWPOINTS, LABELS)
    OUT/site.json             summary: seed, size, tunnel length, graph, drives (format driftmap-sim-site/1)
    OUT/drives/<name>/        drive folders (docs/formats.md) with ground truth
        map-01, map-02, ...   mapping drives (one per face of the centreline graph), with groundings.csv
        loc-01, loc-02, ...   localisation drives (LHD duty cycles)
        loc-01-dust1, ...     obscured copies of each localisation drive (dust1, dust2, water1, water2)

Frames are rendered in chunks on a pool of worker processes (forked); every frame depends only on the
seed, the drive and the frame number, so the output is byte-identical for a seed whatever the number
of workers.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from driftmap.errors import BadInputError, ConflictError
from driftmap.sim import frames as frame_worker
from driftmap.sim.boards import write_calibration_set
from driftmap.sim.geometry import FloatArray
from driftmap.sim.layout import Layout, generate_layout
from driftmap.sim.motion import DrivePlan, plan_localisation, plan_mapping
from driftmap.sim.obscurants import LEVELS, water_centre, water_diameter_px
from driftmap.sim.params import VEHICLE_DEFAULT, camera_rig, site_size
from driftmap.sim.render import Renderer
from driftmap.sim.ride import RIDE_DEFAULT, RideParams, calibrated_rig, floor_px_per_m, ride_motion
from driftmap.sim.rig import CameraRig
from driftmap.sim.routes import Graph
from driftmap.sim.site_files import SITE_FORMAT, DriveSummary, write_drive, write_site_json
from driftmap.sim.survey import write_survey_dxf
from driftmap.sim.trajectory import FramePoses, sample_frames
from driftmap.sim.world import build_world

__all__ = ["SITE_FORMAT", "DriveSummary", "SimulationSummary", "SitePlan", "plan_site", "simulate_site"]

log = logging.getLogger(__name__)

OBSCURANT_NAMES: tuple[str, ...] = ("dust1", "dust2", "water1", "water2")
_CHUNK = 48  # frames per rendering task


@dataclass(frozen=True)
class SimulationSummary:
    """What :func:`simulate_site` wrote."""

    out_dir: Path
    seed: int
    size: str
    tunnel_length_m: float
    drives: tuple[DriveSummary, ...]
    frames_rendered: int  # frames ray-cast (obscured copies not counted)
    frames_written: int  # frame files written, obscured copies included
    seconds: float  # wall-clock time

    def describe(self) -> str:
        """A few lines for people: what was written where, and how fast."""
        kinds = {
            k: sum(1 for d in self.drives if d.kind == k and d.obscurant is None)
            for k in ("mapping", "localisation")
        }
        copies = sum(1 for d in self.drives if d.obscurant is not None)
        return (
            f"{self.size} site (seed {self.seed}): {self.tunnel_length_m:.0f} m of tunnel -> {self.out_dir}\n"
            f"{kinds['mapping']} mapping and {kinds['localisation']} localisation drives"
            f"{f' (+{copies} obscured copies)' if copies else ''}; {self.frames_rendered} frames rendered, "
            f"{self.frames_written} written in {self.seconds:.1f} s ({self.frames_rendered / max(self.seconds, 1e-9):.0f} frames/s)"
        )


@dataclass(frozen=True, eq=False)
class SitePlan:
    """Everything decided before rendering: the layout, the camera, every drive and its frame poses."""

    seed: int
    size: str
    layout: Layout
    rig: CameraRig
    plans: tuple[DrivePlan, ...]  # mapping drives first, then localisation drives
    poses: tuple[FramePoses, ...]  # per drive: frame times, camera floor points (grid m), yaw, groundings


def plan_site(seed: int, size: str, camera: str = "pinhole") -> SitePlan:
    """Lay out the site and plan every drive (no rendering); deterministic per seed.

    Mapping drives come first; the localisation drives share what the mapping leaves of the size's
    frame budget (at least ``min_localisation_frames``). ``camera`` names the rig (:data:`RIGS`): the
    drives are the same for every camera, the ground truth is the floor point under that camera.

    Raises:
        ValueError: an unknown size or camera.
    """
    spec = site_size(size)
    vp = VEHICLE_DEFAULT
    layout = generate_layout(seed, spec)
    rig = CameraRig(camera_rig(camera))
    graph = Graph(layout, vp.turn_max_rad)
    plans = plan_mapping(graph, vp, rig.lever_m, seed)
    used = sum(p.frame_count(vp.fps) for p in plans)
    loc_total = max(spec.frame_budget - used, spec.min_localisation_frames)
    share = max(loc_total // spec.localisation_drives, 1)
    plans += [
        plan_localisation(graph, vp, rig.lever_m, seed, i, share) for i in range(spec.localisation_drives)
    ]
    poses = [
        sample_frames(
            list(p.runs),
            vp.fps,
            rig.lever_m,
            p.start_dwell_s,
            vp.grounding_sigma_m,
            np.random.default_rng([seed, 53, i]),
            p.start_grounding,
        )
        for i, p in enumerate(plans)
    ]
    return SitePlan(seed, size, layout, rig, tuple(plans), tuple(poses))


def _truncate(p: FramePoses, n: int) -> FramePoses:
    return FramePoses(p.t[:n], p.xy[:n], p.yaw[:n], [g for g in p.groundings if g[0] < n])


def simulate_site(
    out_dir: Path,
    *,
    seed: int,
    size: str,
    obscurants: bool = True,
    progress: Callable[[str, float], None] | None = None,
    workers: int | None = None,
    max_frames_per_drive: int | None = None,
    ride: RideParams = RIDE_DEFAULT,
    camera: str = "pinhole",
) -> SimulationSummary:
    """Generate the synthetic site ``size`` for ``seed`` and write it to ``out_dir``.

    Args:
        out_dir: output folder; created if missing, must be empty if it exists.
        seed: non-negative site seed; the same seed gives byte-identical output.
        size: "tiny", "small", "medium", "large" or "mine".
        obscurants: also write dust1/dust2/water1/water2 copies of every localisation drive.
        progress: called with (what is happening, fraction done in [0, 1]).
        workers: rendering processes (default: up to 2, the CPU count).
        max_frames_per_drive: keep only the first frames of every drive (quick previews and tests).
        ride: camera bounce, motion blur and per-drive calibration error (:data:`RIDE_NONE`: a perfect rig).
        camera: the vehicle camera (:data:`~driftmap.sim.params.RIGS`): ``"pinhole"`` (320x240, looking
            ahead) or ``"wide180"`` (paper 000's 944x800 180-degree fisheye at the rear, looking back), which
            also writes chessboard images for calibration and the lens's truth (:mod:`driftmap.sim.boards`).

    Raises:
        BadInputError: a bad seed, size or camera.
        ConflictError: ``out_dir`` exists and is not empty.
    """
    started = time.perf_counter()
    report = progress or (lambda _msg, _frac: None)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise BadInputError(f"seed must be a non-negative integer, got {seed!r}", field="seed")
    try:
        site_size(size)
    except ValueError as exc:
        raise BadInputError(str(exc), field="size") from None
    try:
        camera_rig(camera)
    except ValueError as exc:
        raise BadInputError(str(exc), field="camera") from None
    out_dir = Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        raise ConflictError(f"{out_dir} already exists and is not empty")
    report("planning", 0.0)
    site = plan_site(seed, size, camera)
    layout, plans, rig, vp = site.layout, list(site.plans), site.rig, VEHICLE_DEFAULT
    poses = list(site.poses)
    if max_frames_per_drive is not None:
        poses = [_truncate(p, max(int(max_frames_per_drive), 1)) for p in poses]
    out_dir.mkdir(parents=True, exist_ok=True)
    write_survey_dxf(layout, out_dir / "survey.dxf")
    report("building world", 0.02)
    world = build_world(layout, seed)
    renderer = Renderer(world, rig)
    cameras = [
        calibrated_rig(rig, np.random.default_rng([seed, 79, i]), ride).camera_model
        for i in range(len(plans))
    ]
    total = sum(len(p.t) for p in poses)
    tasks = list(_tasks(plans, poses, world.origin_xy, seed, obscurants, rig, ride))
    summaries: list[DriveSummary] = []
    pending: dict[int, dict[str, list[bytes]]] = {}
    done_frames = 0
    n_workers = workers or min(2, os.cpu_count() or 1)
    for task, images in _run(tasks, renderer, n_workers):
        bucket = pending.setdefault(task.drive, {})
        for variant, data in images.items():
            bucket.setdefault(variant, []).extend(data)
        done_frames += len(task.poses)
        report(f"rendering {plans[task.drive].name}", 0.05 + 0.93 * done_frames / max(total, 1))
        if task.last:
            summaries += write_drive(
                out_dir,
                plans[task.drive],
                poses[task.drive],
                cameras[task.drive],
                vp.fps,
                pending.pop(task.drive),
            )
    if rig.lens is not None:
        report("rendering calibration boards", 0.99)
        write_calibration_set(out_dir / "calibration", rig, seed)
    write_site_json(out_dir, seed, size, camera, layout, rig.camera_model, vp.fps, summaries)
    report("done", 1.0)
    return SimulationSummary(
        out_dir=out_dir,
        seed=seed,
        size=size,
        tunnel_length_m=layout.total_length_m,
        drives=tuple(summaries),
        frames_rendered=total,
        frames_written=sum(s.frames for s in summaries),
        seconds=time.perf_counter() - started,
    )


def _tasks(
    plans: list[DrivePlan],
    poses: list[FramePoses],
    origin: tuple[float, float],
    seed: int,
    obscurants: bool,
    rig: CameraRig,
    ride_params: RideParams,
) -> Iterator[frame_worker.Chunk]:
    size_px = rig.size_px
    blur_px_per_mps = ride_params.exposure_s * floor_px_per_m(rig)
    for i, (plan, p) in enumerate(zip(plans, poses, strict=True)):
        local = p.xy - np.asarray(origin)
        exposure = frame_worker.exposure_curve(p.t, np.random.default_rng([seed, 61, i]))
        speed = _speeds(p)
        ride = np.column_stack(
            [
                ride_motion(p.t, speed, np.random.default_rng([seed, 83, i]), ride_params),
                speed * blur_px_per_mps,
            ]
        )
        variants: list[tuple[str, str, tuple[float, float] | None]] = []
        if obscurants and plan.kind == "localisation":
            for name in OBSCURANT_NAMES:
                level = LEVELS[name]
                centre = None
                if level.kind == "water":
                    d = water_diameter_px(level.water_diameter_paper_px, size_px[0])
                    centre = water_centre((size_px[1], size_px[0]), d, np.random.default_rng([seed, 67, i]))
                variants.append((name, name, centre))
        n = len(p.t)
        for start in range(0, n, _CHUNK):
            stop = min(start + _CHUNK, n)
            yield frame_worker.Chunk(
                drive=i,
                start=start,
                last=stop == n,
                seed=seed,
                poses=np.column_stack([local[start:stop], p.yaw[start:stop]]),
                exposure=exposure[start:stop],
                ride=ride[start:stop],
                variants=tuple(variants),
            )


def _speeds(p: FramePoses) -> FloatArray:
    """(n,) speed of the camera's floor point at each frame, metres per second (0 for one frame)."""
    if len(p.t) < 2:
        return np.zeros(len(p.t))
    step = np.hypot(*np.diff(p.xy, axis=0).T) / np.maximum(np.diff(p.t), 1e-6)
    return np.asarray(np.concatenate([step[:1], (step[:-1] + step[1:]) / 2, step[-1:]]))


def _run(
    tasks: list[frame_worker.Chunk], renderer: Renderer, n_workers: int
) -> Iterator[tuple[frame_worker.Chunk, dict[str, list[bytes]]]]:
    """Render tasks in order, on a pool of forked processes when more than one worker is asked for.

    Forked (where available) so that callers need no ``__main__`` guard and the renderer is shared,
    not pickled; the workers leave OpenCV's thread settings alone (changing them in a forked child
    deadlocks on the thread pool copied from the parent).
    """
    if n_workers <= 1 or len(tasks) <= 1 or multiprocessing.current_process().daemon:  # daemons can't fork
        frame_worker.init_worker(renderer)
        for task in tasks:
            yield task, frame_worker.render_chunk(task)
        return
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    ctx = multiprocessing.get_context(method)
    with ctx.Pool(n_workers, initializer=frame_worker.init_pool_worker, initargs=(renderer,)) as pool:
        yield from zip(tasks, pool.imap(frame_worker.render_chunk, tasks), strict=True)
