"""The UI screenshots in ``docs/``, made by the browser end-to-end tests and copied there.

Runs the e2e tests that end on each pictured view (``tests/e2e/``: a real ``driftmap serve`` on the tiny site
and Debian's chromium at 1366x768, which save screenshots to ``tests/e2e/artifacts/``), then copies each
picture to its ``docs/`` name. A picture over ``--max-kb`` is reduced to an adaptive 256-colour palette (the UI's
flat dark theme keeps its look) so the repository stays small. Needs ``frontend/dist`` built (``make frontend``)
and chromium (``make system-packages``). Usage: ``.venv/bin/python bench/ui_screenshots.py [--max-kb 300]``
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

from PIL import Image

REPO = Path(__file__).resolve().parents[1]
ARTIFACTS = REPO / "tests" / "e2e" / "artifacts"
DOCS = REPO / "docs"

# docs/ name -> (the e2e test that saves it, its artefact name)
SHOTS: dict[str, tuple[str, str]] = {
    "ui_monitoring.png": (
        "tests/e2e/test_monitoring.py::TestLatestFrame::test_the_panel_shows_exactly_the_selected_vehicles_latest_frame",
        "ui_monitoring_colours",
    ),
    "ui_events.png": (
        "tests/e2e/test_monitoring.py::TestEvents::test_an_event_acknowledged_by_one_user_shows_acknowledged_to_another",
        "ui_events",
    ),
    "ui_camera_obscured.png": (
        "tests/e2e/test_monitoring.py::TestObscuredCamera::test_dust_on_the_lens_shows_camera_obscured_and_an_alert",
        "ui_obscured",
    ),
    "ui_replay.png": (
        "tests/e2e/test_monitoring.py::TestReplay::test_replay_a_range_with_speed_scrubber_and_follow",
        "ui_replay",
    ),
    "ui_grounding.png": (
        "tests/e2e/test_ui.py::TestGrounding::test_ground_a_keyframe_in_placing_mode_undo_redo_delete",
        "ui_grounding",
    ),
    "ui_build_presets.png": (
        "tests/e2e/test_ui.py::TestGrounding::test_a_second_build_is_refused_and_each_preset_is_explained",
        "ui_build_presets",
    ),
    "ui_uploads.png": (
        "tests/e2e/test_ui.py::TestAdmin::test_copy_a_token_see_when_each_vehicle_was_last_seen_and_upload_a_plan_with_progress",
        "ui_uploads",
    ),
    "ui_tablet.png": (
        "tests/e2e/test_ui.py::TestLayout::test_a_tablet_gets_a_menu_a_full_width_map_and_a_pull_up_panel_and_nothing_overflows",
        "ui_tablet",
    ),
    "ui_cameras.png": (
        "tests/e2e/test_cameras_ui.py::TestCameraSetUp::test_fit_the_ground_save_a_profile_and_give_it_to_a_vehicle",
        "ui_cameras",
    ),
}


def run_tests(tests: list[str]) -> None:
    """Run the e2e tests in one session (one server), from the repository root; stop on a failure."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO / "backend"), str(REPO)]))}
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *tests]
    subprocess.run(cmd, cwd=REPO, env=env, check=True)


def copy_small(src: Path, dst: Path, max_kb: int) -> int:
    """Copy a PNG, reduced to a 256-colour palette when it is over ``max_kb``; returns the size in bytes."""
    shutil.copyfile(src, dst)
    if dst.stat().st_size > max_kb * 1024:
        with Image.open(src) as image:
            small = image.convert("RGB").quantize(
                colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
            )
            small.save(dst, optimize=True)
    return dst.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-kb", type=int, default=300, help="reduce a picture over this size, KiB")
    parser.add_argument("--only", nargs="*", default=None, help="docs/ names to remake (default: all)")
    args = parser.parse_args()
    shots = {name: SHOTS[name] for name in (args.only or SHOTS)}
    for artefact in {a for _, a in shots.values()}:
        (ARTIFACTS / f"{artefact}.png").unlink(missing_ok=True)
    run_tests(sorted({test for test, _ in shots.values()}))
    for name, (_, artefact) in shots.items():
        size = copy_small(ARTIFACTS / f"{artefact}.png", DOCS / name, args.max_kb)
        print(f"docs/{name}: {size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
