"""The written site: layout on disk, formats, ground truth against pixels, obscured copies, determinism."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.errors import BadInputError, ConflictError
from driftmap.formats.drive_folder import DriveFolder, read_drive_folder
from driftmap.sim import SitePlan, simulate_site
from driftmap.sim.obscurants import water_diameter_px
from driftmap.sim.rig import CameraRig
from tests.sim.conftest import SEED, WRITTEN_FRAMES, WrittenSite
from tests.sim.truth_warp import ncc_predicted

NCC_MATCH = 0.5  # normalised cross-correlation of the ROI predicted through truth + homography
NCC_MARGIN = 0.25  # ... and by how much it beats a pose 0.25 m off
DUST_TOL = 0.006  # share of pixels


def _drive(site: WrittenSite, name: str) -> DriveFolder:
    return read_drive_folder(site.path / "drives" / name)


def _gray(folder: DriveFolder, i: int) -> NDArray[np.uint8]:
    img = cv2.imread(str(folder.frame_files[i]), cv2.IMREAD_UNCHANGED)
    assert img is not None and img.dtype == np.uint8 and img.ndim == 2
    return np.asarray(img)


class TestOutputLayout:
    def test_files_and_site_json(self, tiny_site: WrittenSite) -> None:
        root = tiny_site.path
        assert (root / "survey.dxf").is_file()
        info = json.loads((root / "site.json").read_text())
        assert info["format"] == "driftmap-sim-site/1" and info["seed"] == SEED and info["size"] == "tiny"
        assert info["tunnel_length_m"] == pytest.approx(tiny_site.summary.tunnel_length_m, abs=0.01)
        names = sorted(d["name"] for d in info["drives"])
        assert names == sorted(p.name for p in (root / "drives").iterdir())
        kinds = {d["name"]: d["kind"] for d in info["drives"]}
        assert {"map-01", "map-02", "loc-01"} <= set(kinds) and kinds["loc-01-water2"] == "localisation"

    def test_truth_is_the_plan(self, tiny_site: WrittenSite, tiny_plan: SitePlan) -> None:
        for plan, poses in zip(tiny_plan.plans, tiny_plan.poses, strict=True):
            folder = _drive(tiny_site, plan.name)
            assert len(folder.frames) == min(WRITTEN_FRAMES, len(poses.t))
            for r in folder.frames[::17]:
                assert (r.t_s, r.x_m, r.y_m) == pytest.approx(
                    (poses.t[r.frame], poses.xy[r.frame, 0], poses.xy[r.frame, 1]), abs=1e-3
                )
            written = np.array([(g.frame, g.x_m, g.y_m) for g in folder.groundings]).reshape(-1, 3)
            planned = np.array([g for g in poses.groundings if g[0] < WRITTEN_FRAMES]).reshape(-1, 3)
            assert written.shape == planned.shape and np.allclose(written, planned, atol=1e-3)

    def test_every_drive_reads_back(self, tiny_site: WrittenSite) -> None:
        camera = CameraRig().camera_model
        for d in tiny_site.summary.drives:
            folder = _drive(tiny_site, d.name)
            assert folder.meta.name == d.name and folder.meta.kind == d.kind and folder.meta.fps == 10.0
            assert folder.meta.camera == camera
            assert len(folder.frames) == d.frames and all(r.has_truth for r in folder.frames)
            assert bool(folder.groundings) == (d.kind == "mapping")


class TestTruthAgreesWithPixels:
    def test_consecutive_frames_are_related_by_truth_and_homography(self, tiny_site: WrittenSite) -> None:
        folder = _drive(tiny_site, "map-01")
        xy = np.array([[r.x_m, r.y_m] for r in folder.frames], dtype=float)
        step = np.hypot(*np.diff(xy, axis=0).T)
        moving = [int(i) for i in np.flatnonzero((step > 0.15) & (step < 0.5))[::10][:5]]
        assert moving
        for k in moving:
            good = ncc_predicted(folder, k, 0.0, lambda i: _gray(folder, i).astype(np.float32))
            wrong = ncc_predicted(folder, k, 0.25, lambda i: _gray(folder, i).astype(np.float32))
            assert good > NCC_MATCH and good > wrong + NCC_MARGIN, (k, good, wrong)


class TestObscuredCopies:
    @pytest.mark.parametrize("level", ["dust1", "dust2", "water1", "water2"])
    def test_same_truth_other_name(self, tiny_site: WrittenSite, level: str) -> None:
        src, copy = tiny_site.path / "drives" / "loc-01", tiny_site.path / "drives" / f"loc-01-{level}"
        assert (src / "frames.csv").read_bytes() == (copy / "frames.csv").read_bytes()
        assert json.loads((copy / "drive.json").read_text())["name"] == f"loc-01-{level}"

    @pytest.mark.parametrize(("level", "fraction"), [("dust1", 0.05), ("dust2", 0.10)])
    def test_dust_greys_the_stated_share_of_pixels(
        self, tiny_site: WrittenSite, level: str, fraction: float
    ) -> None:
        clean, dusty = _drive(tiny_site, "loc-01"), _drive(tiny_site, f"loc-01-{level}")
        patterns = []
        for i in (0, 7, 31):
            a, b = _gray(clean, i), _gray(dusty, i)
            changed = a != b
            assert np.all(b[changed] == 128)
            greyed = (b == 128).mean() - (a == 128).mean() * (1 - fraction)
            assert greyed == pytest.approx(fraction, abs=DUST_TOL)
            patterns.append(changed)
        assert not np.array_equal(patterns[0], patterns[1])  # a new pattern every frame

    @pytest.mark.parametrize(("level", "paper_px"), [("water1", 90.0), ("water2", 150.0)])
    def test_water_blurs_one_static_circle(self, tiny_site: WrittenSite, level: str, paper_px: float) -> None:
        clean, wet = _drive(tiny_site, "loc-01"), _drive(tiny_site, f"loc-01-{level}")
        diameter = water_diameter_px(paper_px, 320)
        union = np.zeros((240, 320), bool)
        for i in range(0, len(clean.frames), 40):
            union |= _gray(clean, i) != _gray(wet, i)
        vv, uu = np.nonzero(union)
        assert uu.size > 0.5 * math.pi * (diameter / 2) ** 2  # most of the disc changes somewhere
        centre = np.array([uu.mean(), vv.mean()])
        radius = np.hypot(uu - centre[0], vv - centre[1]).max()
        assert radius <= diameter / 2 + 1.0


class TestDeterminism:
    def test_same_seed_same_bytes(self, tmp_path: Path) -> None:
        trees = []
        for run in ("a", "b"):
            out = tmp_path / run
            simulate_site(out, seed=3, size="tiny", max_frames_per_drive=15, workers=1 if run == "a" else 2)
            trees.append({p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()})
        assert trees[0].keys() == trees[1].keys() and len(trees[0]) > 50
        assert all(trees[0][k] == trees[1][k] for k in trees[0])

    def test_other_seed_other_frames(self, tmp_path: Path, tiny_site: WrittenSite) -> None:
        out = tmp_path / "other"
        simulate_site(out, seed=SEED + 1, size="tiny", obscurants=False, max_frames_per_drive=3, workers=1)
        assert not (out / "drives" / "loc-01-dust1").exists()
        first = "drives/map-01/frames/000000.png"
        assert (out / first).read_bytes() != (tiny_site.path / first).read_bytes()


class TestErrors:
    def test_refuses_a_non_empty_folder(self, tmp_path: Path) -> None:
        (tmp_path / "keep.txt").write_text("x")
        with pytest.raises(ConflictError):
            simulate_site(tmp_path, seed=1, size="tiny")

    @pytest.mark.parametrize(("seed", "size"), [(1, "huge"), (-1, "tiny")])
    def test_bad_arguments(self, tmp_path: Path, seed: int, size: str) -> None:
        with pytest.raises(BadInputError):
            simulate_site(tmp_path / "x", seed=seed, size=size)
