"""The mounting check (``driftmap camera check --turn-deg``) on the turns of a simulated drive.

Finds the stretches of ``--frames`` frames of a drive folder with the largest true turns (each starting at a
multiple of 25 frames, not overlapping), and runs the check on each with the true turn stated and the camera's
lever set to ``--y-c`` (default: the drive's): odometry's turn with that lever, the floor's fitted lever (when
determined) and the lever with which odometry turns through the stated angle. Prints a row per stretch and the
mean lever of the left and of the right turns. A simulated site's drives carry the simulator's camera block;
``--camera`` checks another one (e.g. the one driftmap calibrated from the site's boards).

Usage: ``.venv/bin/python bench/turn_check_stretches.py DRIVE_DIR [--frames 150] [--count 5] [--y-c M]
[--camera camera.json]``
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "backend"))

from driftmap.core.odometry.drive import match_frames  # noqa: E402
from driftmap.core.odometry.turn_check import check_turn  # noqa: E402
from driftmap.formats.camera_setup import complete_camera, read_camera_file  # noqa: E402
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder  # noqa: E402
from driftmap.formats.frame_images import decode_gray  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("drive", type=Path, help="a simulated drive folder (frames.csv with the true yaw)")
    parser.add_argument("--frames", type=int, default=150, help="frames per stretch")
    parser.add_argument("--count", type=int, default=5, help="stretches to check")
    parser.add_argument("--y-c", type=float, default=None, help="the lever to start from, metres")
    parser.add_argument("--camera", type=Path, default=None, help="camera.json to check instead")
    args = parser.parse_args()
    folder = read_drive_folder(args.drive)
    camera = folder.meta.camera
    if args.camera is not None:
        camera = complete_camera(read_camera_file(args.camera), args.camera) or camera
    if args.y_c is not None:
        camera = dataclasses.replace(camera, y_c_m=args.y_c)
    rows = folder.frames
    if any(r.yaw_rad is None for r in rows):
        raise SystemExit(f"{args.drive}: frames.csv has no true yaw")
    yaw = np.unwrap(np.array([r.yaw_rad for r in rows], dtype=np.float64))
    starts = range(0, len(rows) - args.frames, 25)
    ranked = sorted(starts, key=lambda s: -abs(yaw[s + args.frames] - yaw[s]))
    chosen: list[int] = []
    for s in ranked:
        if all(abs(s - c) >= args.frames for c in chosen):
            chosen.append(s)
        if len(chosen) == args.count:
            break
    frames = [decode_gray(data, str(args.drive)) for _row, data in iter_frame_images(folder)]
    print(f"{args.drive.name}: camera y_c {camera.y_c_m:.2f} m, stretches of {args.frames} frames")
    print(f"{'frames':>11} {'true turn':>9} {'odometry':>9} {'fitted y_c':>11} {'turn y_c':>9}")
    levers: dict[str, list[float]] = {"left": [], "right": []}
    for s in sorted(chosen):
        stated = float(yaw[s + args.frames] - yaw[s])
        check = check_turn(match_frames(frames[s : s + args.frames + 1], camera), camera, stated)
        fitted = f"{check.fitted_y_c_m:.2f}" if check.fitted_y_c_m is not None else "-"
        turn = f"{check.turn_y_c_m:.2f}" if check.turn_y_c_m is not None else "-"
        print(
            f"{s:>5}-{s + args.frames:<5} {math.degrees(stated):>+9.1f} {math.degrees(check.turned_rad):>+9.1f} "
            f"{fitted:>11} {turn:>9}"
        )
        if check.turn_y_c_m is not None:
            levers["left" if stated > 0 else "right"].append(check.turn_y_c_m)
    means = {side: float(np.mean(v)) for side, v in levers.items() if v}
    print(
        "turn y_c, mean: " + ", ".join(f"{side} {m:.2f} m ({len(levers[side])})" for side, m in means.items())
    )
    if len(means) == 2:
        print(f"left and right averaged: {0.5 * (means['left'] + means['right']):.2f} m")


if __name__ == "__main__":
    main()
