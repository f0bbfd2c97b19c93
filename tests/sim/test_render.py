"""The renderer against the camera model: world-anchored pixels, eq. 1-2 motion, determinism."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.sim.geometry import heading_at, point_at
from driftmap.sim.layout import Layout, generate_layout
from driftmap.sim.params import SIZES
from driftmap.sim.render import RENDER_DEFAULT, Renderer
from driftmap.sim.rig import CameraRig
from driftmap.sim.world import World, build_world

MARKER_PX_TOL = 1.0  # a floor marker lands within a pixel of its projection
SHIFT_REL_TOL = 0.15  # measured image shifts within 15 % of eq. 1 / eq. 2
NOISELESS = replace(RENDER_DEFAULT, noise=False)


@pytest.fixture(scope="module")
def layout() -> Layout:
    return generate_layout(2, SIZES["tiny"])


@pytest.fixture(scope="module")
def world(layout: Layout) -> World:
    return build_world(layout, 2)


@pytest.fixture(scope="module")
def rig() -> CameraRig:
    return CameraRig()


def _pose(layout: Layout, world: World) -> tuple[NDArray[np.float64], float]:
    """A pose (grid xy, yaw) in the middle of the longest tunnel, looking along it."""
    edge = max(layout.edges, key=lambda e: e.length_m)
    s = edge.length_m / 2 - 4.0
    return point_at(edge.polyline, s), heading_at(edge.polyline, s)


def _render(renderer: Renderer, world: World, xy: NDArray[np.float64], yaw: float) -> NDArray[np.float32]:
    local = world.to_local(xy)
    return renderer.render(float(local[0]), float(local[1]), yaw, 1.0, 0).astype(np.float32)


def _flat(img: NDArray[np.float32]) -> NDArray[np.float32]:
    """Divide out the local mean: the headlight pattern is fixed in the image, the texture moves."""
    return np.asarray(img / cv2.GaussianBlur(img, (0, 0), 6.0) - 1.0, dtype=np.float32)


def _track(
    a: NDArray[np.float32], b: NDArray[np.float32], rig: CameraRig, search_px: int = 12
) -> tuple[float, float]:
    """Image shift (du, dv) of the floor at the ROI centre from frame a to b: SSD block matching
    of an 80x16 patch (as ground-plane odometry does), parabolic sub-pixel refinement."""
    x, y, w, h = rig.camera_model.ground_roi_px
    uc, vc = x + w // 2, y + h // 2
    A, B = _flat(a), _flat(b)
    tpl = A[vc - 8 : vc + 8, uc - 40 : uc + 40]
    win = B[vc - 8 - search_px : vc + 8 + search_px, uc - 40 - search_px : uc + 40 + search_px]
    cost = cv2.matchTemplate(win, tpl, cv2.TM_SQDIFF)
    j, i = np.unravel_index(int(np.argmin(cost)), cost.shape)

    def sub(lo: float, mid: float, hi: float) -> float:
        den = lo - 2 * mid + hi
        return 0.5 * (lo - hi) / den if den > 0 else 0.0

    dv = j - search_px + sub(cost[j - 1, i], cost[j, i], cost[j + 1, i])
    du = i - search_px + sub(cost[j, i - 1], cost[j, i], cost[j, i + 1])
    return float(du), float(dv)


def _birdseye(img: NDArray[np.float32], H: NDArray[np.float64], res_m: float) -> NDArray[np.float32]:
    """The floor 1.6-3.6 m ahead, +-1 m sideways, resampled to ``res_m`` per pixel through H^-1;
    bird's-eye row i is x = 3.6 - i res (forward), column j is y = 1 - j res (left)."""
    bird_to_floor = np.array([[0.0, -res_m, 3.6], [-res_m, 0.0, 1.0], [0.0, 0.0, 1.0]])
    size = (int(2.0 / res_m), int(2.0 / res_m))
    out = cv2.warpPerspective(
        img, np.linalg.inv(H) @ bird_to_floor, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    )
    return np.asarray(out / cv2.GaussianBlur(out, (0, 0), 20.0) - 1.0, dtype=np.float32)


class TestFloorMarker:
    @pytest.mark.parametrize("marker_f", [(3.0, 0.5), (2.2, -0.8), (5.0, 1.5)])
    def test_marker_lands_on_its_projection(
        self, layout: Layout, world: World, rig: CameraRig, marker_f: tuple[float, float]
    ) -> None:
        xy, yaw = _pose(layout, world)
        c, s = math.cos(yaw), math.sin(yaw)
        mx, my = marker_f
        marker_w = xy + np.array([c * mx - s * my, s * mx + c * my])
        plain = _render(Renderer(world, rig, NOISELESS), world, xy, yaw)
        marked_world = world.with_spots(np.array([[marker_w[0], marker_w[1], 0.05, 1.0, 1.6]]))
        marked = _render(Renderer(marked_world, rig, NOISELESS), marked_world, xy, yaw)
        diff = np.clip(marked - plain, 0.0, None)
        assert diff.max() > 20
        vv, uu = np.nonzero(diff > 0.1 * diff.max())
        wts = diff[vv, uu]
        found = np.array([np.sum(uu * wts), np.sum(vv * wts)]) / np.sum(wts)
        H = rig.camera_model.homography()
        assert H is not None
        q = np.linalg.inv(H) @ np.array([mx, my, 1.0])
        assert np.hypot(*(found - q[:2] / q[2])) < MARKER_PX_TOL


class TestMotionInTheImage:
    @pytest.mark.parametrize("d_m", [0.05, 0.1, 0.2])
    def test_forward_motion_moves_the_floor_down_by_d_over_k_y(
        self, layout: Layout, world: World, rig: CameraRig, d_m: float
    ) -> None:
        xy, yaw = _pose(layout, world)
        r = Renderer(world, rig, NOISELESS)
        a = _render(r, world, xy, yaw)
        b = _render(r, world, xy + d_m * np.array([math.cos(yaw), math.sin(yaw)]), yaw)
        du, dv = _track(a, b, rig)
        cam = rig.camera_model
        assert dv == pytest.approx(cam.forward_sign * d_m / cam.k_y_m_per_px, rel=SHIFT_REL_TOL)  # eq. 2
        assert abs(du) < 1.0

    def test_rotation_about_the_rear_axle_follows_eq_1(
        self, layout: Layout, world: World, rig: CameraRig
    ) -> None:
        cam = rig.camera_model
        xy, yaw = _pose(layout, world)
        theta = math.radians(1.5)
        rear = xy - cam.y_c_m * np.array([math.cos(yaw), math.sin(yaw)])
        turned = rear + cam.y_c_m * np.array([math.cos(yaw + theta), math.sin(yaw + theta)])
        r = Renderer(world, rig, NOISELESS)
        du, dv = _track(_render(r, world, xy, yaw), _render(r, world, turned, yaw + theta), rig)
        # eq. 1: theta = atan(x_p k_x / (y_c + y_h)); turning left moves the floor right (+u)
        assert du == pytest.approx(
            math.tan(theta) * (cam.y_c_m + cam.y_h_m) / cam.k_x_m_per_px, rel=SHIFT_REL_TOL
        )
        assert abs(dv) < 1.0

    def test_ground_homography_is_metric(self, layout: Layout, world: World, rig: CameraRig) -> None:
        """Through the written homography, driving d forward shifts the bird's-eye floor by d."""
        xy, yaw = _pose(layout, world)
        H = rig.camera_model.homography()
        assert H is not None
        r = Renderer(world, rig, NOISELESS)
        res = 0.01
        d = 0.15
        a = _birdseye(_render(r, world, xy, yaw), H, res)
        b = _birdseye(_render(r, world, xy + d * np.array([math.cos(yaw), math.sin(yaw)]), yaw), H, res)
        (dx, dy), _ = cv2.phaseCorrelate(a, b, cv2.createHanningWindow(a.shape[::-1], cv2.CV_32F))
        assert dy * res == pytest.approx(d, abs=0.01) and abs(dx * res) < 0.01


class TestFrames:
    def test_deterministic_and_noise_seeded(self, layout: Layout, world: World, rig: CameraRig) -> None:
        xy, yaw = _pose(layout, world)
        local = world.to_local(xy)
        r = Renderer(world, rig)
        a = r.render(float(local[0]), float(local[1]), yaw, 1.0, [1, 2])
        b = Renderer(world, rig).render(float(local[0]), float(local[1]), yaw, 1.0, [1, 2])
        c = r.render(float(local[0]), float(local[1]), yaw, 1.0, [1, 3])
        assert a.dtype == np.uint8 and a.shape == (240, 320)
        assert np.array_equal(a, b) and not np.array_equal(a, c)

    def test_headlight_lights_the_near_floor_and_exposure_scales(
        self, layout: Layout, world: World, rig: CameraRig
    ) -> None:
        xy, yaw = _pose(layout, world)
        local = world.to_local(xy)
        r = Renderer(world, rig, NOISELESS)
        img = r.render(float(local[0]), float(local[1]), yaw, 1.0, 0).astype(float)
        dark = r.render(float(local[0]), float(local[1]), yaw, 0.5, 0).astype(float)
        x, y, w, h = rig.camera_model.ground_roi_px
        near_floor = img[y : y + h, x : x + w].mean()
        far_centre = img[70:90, 140:180].mean()  # down the tunnel, tens of metres away
        assert near_floor > 60 and near_floor > 2 * far_centre
        assert dark.mean() < img.mean()

    def test_floor_texture_has_detail_for_odometry(
        self, layout: Layout, world: World, rig: CameraRig
    ) -> None:
        xy, yaw = _pose(layout, world)
        x, y, w, h = rig.camera_model.ground_roi_px
        roi = _render(Renderer(world, rig, NOISELESS), world, xy, yaw)[y : y + h, x : x + w]
        gy = np.abs(np.diff(roi, axis=0)).mean()
        assert gy > 2.0  # grey levels per pixel row: gravel, not a smooth gradient
