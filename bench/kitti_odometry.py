"""Ground-plane visual odometry on the two KITTI clips: dead reckoning against ground truth.

For each clip (``shared/data/kitti/kitti-clip-{1,2}``) and each model, integrates the odometry from the
first frame's true pose and prints distance travelled, final position error (absolute and as a
percentage of the distance), final heading error and the median wall-clock time per step. Models:

* ``birdseye``: the homography (bird's-eye) model with horizon and rotation-centre self-calibration, the
  horizon tracked along the drive where it demonstrably changes (``core/odometry/pitch``; the default);
* ``birdseye-one-horizon``: the same with one (median) horizon for the whole drive;
* ``birdseye-fixed-yc``: the same with the rotation centre fixed at drive.json's ``y_c``;
* ``birdseye-raw``: no self-calibration, i.e. the drive.json homography and ``y_c`` as given;
* ``linear``: the paper's linear k_x/k_y model (eq. 1, 2).

Two more columns split each final error by its source, step by step against the ground truth:
``head-only %`` integrates the true step translations with our heading changes, ``step-only %`` our step
translations with the true heading changes (the two add roughly in quadrature).

``--height-from-check`` adds a table in which no camera height comes from the dataset: the camera height of
each clip is scaled by a guess (0.8, 1.0 and 1.2 times the dataset's 1.65 m), corrected by driftmap's scale
check (``camera check --distance-m``) on clip 1, a straight drive whose true length stands for a measured
distance, repeated until it agrees within 0.5 %, and clip 2 (another KITTI sequence of the same car, its own
intrinsics) is dead-reckoned with its height scaled by the same factor.

Writes a plot of estimated against true trajectories to ``bench/out/kitti_odometry.png`` and copies
it to ``docs/evaluation/kitti_odometry.png``. Ground truth positions are the camera's floor point, as ours.

Usage: ``.venv/bin/python bench/kitti_odometry.py [--data ../shared/data/kitti] [--height-from-check]``
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import itertools
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import DeadReckoning, compose, dead_reckon
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, ODOMETRY_PAPER, OdometryParams

ROOT = Path(__file__).resolve().parents[1]
MODELS: dict[str, OdometryParams] = {
    "birdseye": ODOMETRY_DEFAULT,
    "birdseye-one-horizon": dataclasses.replace(ODOMETRY_DEFAULT, pitch_window_m=0.0),
    "birdseye-fixed-yc": dataclasses.replace(ODOMETRY_DEFAULT, calibrate_lever=False),
    "birdseye-raw": dataclasses.replace(ODOMETRY_DEFAULT, self_calibrate=False),
    "linear": ODOMETRY_PAPER,
}
TARGET_PCT = 5.0


def load_clip(folder: Path) -> tuple[CameraModel, NDArray[np.float64], NDArray[np.uint8]]:
    """Camera, ground truth ``(N, 3)`` [x_m, y_m, yaw_rad] and gray frames ``(N, H, W)`` of a drive folder."""
    try:
        from driftmap.formats.drive_folder import read_drive_folder
        from driftmap.formats.frame_images import decode_gray
    except ImportError:  # the shared reader is not there yet: a minimal parse of the same format
        meta = json.loads((folder / "drive.json").read_text())["camera"]
        hom = meta.get("ground_homography")
        camera = CameraModel(
            meta["width"], meta["height"], tuple(meta["ground_roi"]), meta["k_x"], meta["k_y"], meta["y_c"],
            meta["y_h"], meta.get("forward_sign", 1), tuple(tuple(r) for r in hom) if hom else None,
        )  # fmt: skip
        with (folder / "frames.csv").open() as fh:
            rows = list(csv.DictReader(fh))
        truth = np.array([[float(r["x"]), float(r["y"]), float(r["yaw"])] for r in rows])
        files = [folder / "frames" / f"{int(r['frame']):06d}.png" for r in rows]
        frames = np.stack(
            [np.asarray(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), dtype=np.uint8) for f in files]
        )
        return camera, np.asarray(truth, dtype=np.float64), frames
    drive = read_drive_folder(folder)
    truth = np.array([[r.x_m, r.y_m, r.yaw_rad] for r in drive.frames], dtype=np.float64)
    frames = np.stack([decode_gray(f.read_bytes(), f) for f in drive.frame_files]).astype(np.uint8)
    return drive.meta.camera, truth, frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "kitti")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "out" / "kitti_odometry.png")
    parser.add_argument("--height-from-check", action="store_true", help="also the scale-check table")
    args = parser.parse_args()
    clips = sorted(p for p in args.data.glob("kitti-clip-*") if p.is_dir())
    if not clips:
        raise SystemExit(f"no KITTI clips under {args.data}")
    header = (
        f"{'clip':<13} {'model':<20} {'dist m':>7} {'err m':>6} {'err %':>6} {'yaw err':>8} "
        f"{'head-only %':>11} {'step-only %':>11} {'ms/step':>8} {'horizon px':>10} {'y_c m':>6}"
    )
    print(header)
    print("-" * len(header))
    results: dict[str, dict[str, DeadReckoning]] = {}
    truths: dict[str, NDArray[np.float64]] = {}
    for clip in clips:
        camera, truth, frames = load_clip(clip)
        truths[clip.name] = truth
        distance = float(np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1).sum())
        results[clip.name] = {}
        for name, params in MODELS.items():
            run = dead_reckon(frames, camera, params, start_wT=tuple(truth[0]))
            results[clip.name][name] = run
            err = float(np.linalg.norm(run.wTi[-1, :2] - truth[-1, :2]))
            yaw_err = float(np.angle(np.exp(1j * (run.wTi[-1, 2] - truth[-1, 2]))))
            flag = "" if 100 * err / distance <= TARGET_PCT else "  > target"
            head_only, step_only = split_error(run, truth)
            print(
                f"{clip.name:<13} {name:<20} {distance:>7.1f} {err:>6.2f} {100 * err / distance:>6.1f} "
                f"{yaw_err:>+8.3f} {100 * head_only / distance:>11.1f} {100 * step_only / distance:>11.1f} "
                f"{np.median(run.ms_per_step):>8.0f} {run.horizon_offset_px:>10.1f} {run.lever_m:>6.2f}{flag}"
            )
    if args.height_from_check:
        height_from_check(args.data / "kitti-clip-1", args.data / "kitti-clip-2")
    plot(results, truths, args.out)
    docs = ROOT / "docs" / "evaluation" / "kitti_odometry.png"
    docs.parent.mkdir(exist_ok=True)
    shutil.copyfile(args.out, docs)
    print(f"plot: {args.out} (copied to {docs.relative_to(ROOT)})")


def height_from_check(straight: Path, other: Path, guesses: tuple[float, ...] = (0.8, 1.0, 1.2)) -> None:
    """Print clip ``other``'s odometry error with the camera height found by the scale check on ``straight``."""
    from driftmap.core.odometry.scale_check import scale_camera
    from driftmap.services.cameras.drive_check import check_drive_scale

    cam1, truth1, frames1 = load_clip(straight)
    cam2, truth2, frames2 = load_clip(other)
    heading = np.array([np.cos(truth1[0, 2]), np.sin(truth1[0, 2])])
    measured = float((truth1[-1, :2] - truth1[0, :2]) @ heading)
    distance = float(np.linalg.norm(np.diff(truth2[:, :2], axis=0), axis=1).sum())
    print(
        f"\ncamera height from the scale check on {straight.name} ({measured:.2f} m), applied to {other.name}"
    )
    print(f"{'guess':>6} {'checks':>6} {'height':>7} {other.name + ' err %':>18}")
    for guess in guesses:
        factor, checks = guess, 0
        while checks < 6:
            checks += 1
            result, _ = check_drive_scale(frames1, scale_camera(cam1, factor), measured)
            factor *= result.ratio
            if abs(result.ratio - 1) < 0.005:
                break
        run = dead_reckon(frames2, scale_camera(cam2, factor), start_wT=tuple(truth2[0]))
        err = float(np.linalg.norm(run.wTi[-1, :2] - truth2[-1, :2]))
        print(f"{guess:>6.2f} {checks:>6d} {factor:>7.4f} {100 * err / distance:>18.1f}")


def relative_steps(wTi: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(N - 1, 3)`` steps ``[x_m, y_m, yaw_rad]`` of each pose in the previous one's frame."""
    out = []
    for (x0, y0, a0), (x1, y1, a1) in itertools.pairwise(wTi):
        c, s = np.cos(a0), np.sin(a0)
        dx, dy = x1 - x0, y1 - y0
        out.append((c * dx + s * dy, -s * dx + c * dy, np.angle(np.exp(1j * (a1 - a0)))))
    return np.asarray(out, dtype=np.float64).reshape(-1, 3)


def split_error(run: DeadReckoning, truth: NDArray[np.float64]) -> tuple[float, float]:
    """Final position errors (m) of (true translations + our headings, our translations + true headings)."""
    ours, true = relative_steps(run.wTi), relative_steps(truth)
    errors = []
    for mixed in (np.c_[true[:, :2], ours[:, 2]], np.c_[ours[:, :2], true[:, 2]]):
        pose = truth[0]
        for step in mixed:
            pose = compose(pose, step)
        errors.append(float(np.linalg.norm(pose[:2] - truth[-1, :2])))
    return errors[0], errors[1]


def plot(
    results: dict[str, dict[str, DeadReckoning]], truths: dict[str, NDArray[np.float64]], out: Path
) -> None:
    """Estimated against true trajectories, one panel per clip."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {
        "birdseye": ("tab:blue", "-"),
        "birdseye-one-horizon": ("tab:purple", (0, (5, 2))),
        "birdseye-fixed-yc": ("tab:green", "-."),
        "birdseye-raw": ("tab:blue", ":"),
        "linear": ("tab:orange", "--"),
    }
    fig, axes = plt.subplots(1, len(results), figsize=(5.2 * len(results), 4.6))
    for ax, (clip, runs) in zip(np.atleast_1d(axes), results.items(), strict=True):
        truth = truths[clip]
        ax.plot(truth[:, 0], truth[:, 1], color="black", lw=2.5, label="ground truth")
        for name, run in runs.items():
            color, ls = styles.get(name, ("gray", "-"))
            ax.plot(run.wTi[:, 0], run.wTi[:, 1], color=color, ls=ls, lw=1.6, label=name)
        ax.plot(*truth[0, :2], "ko", ms=5)
        ax.set_title(clip)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Ground-plane visual odometry, dead reckoning from the first true pose")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    main()
