"""Where things are on the map in the browser: the survey point under a page pixel (read from the grid readout)
and back, whether a pixel is plain map (no legend, layer list or map button over it), and the survey's lines
as the server stores them (distances to them, inside the walls or not)."""

from __future__ import annotations

import math
import re
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray
from playwright.sync_api import Page

from tests.e2e.conftest import Server

DEADLINE_S = 60.0


def readout_at(page: Page, px: float, py: float) -> tuple[float, float]:
    """The survey point under the mouse at page pixel ``(px, py)``, read from the map's grid readout."""
    readout = page.get_by_test_id("grid-readout")
    before = readout.inner_text()
    page.mouse.move(px, py)
    deadline = time.monotonic() + DEADLINE_S
    while True:
        text = readout.inner_text()
        found = re.search(r"E (-?[\d.]+)\s+N (-?[\d.]+)", text)
        if found and text != before:
            return float(found.group(1)), float(found.group(2))
        assert time.monotonic() < deadline, f"the readout did not follow the mouse: {text!r}"
        page.wait_for_timeout(50)


def map_scale(page: Page) -> tuple[float, float, float, float, float]:
    """A page pixel, the survey point under it and the map's metres per pixel, measured through the readout."""
    box = page.get_by_test_id("map").bounding_box()
    assert box is not None
    ax, ay = box["x"] + 0.3 * box["width"], box["y"] + 0.3 * box["height"]
    bx, by = box["x"] + 0.7 * box["width"], box["y"] + 0.7 * box["height"]
    (ea, na), (eb, nb) = readout_at(page, ax, ay), readout_at(page, bx, by)
    m_per_px_x, m_per_px_y = (eb - ea) / (bx - ax), (na - nb) / (by - ay)  # north is up
    assert m_per_px_x > 0 and math.isclose(m_per_px_x, m_per_px_y, rel_tol=0.02), (m_per_px_x, m_per_px_y)
    return ax, ay, ea, na, m_per_px_x


def pixel_of(page: Page, x: float, y: float) -> tuple[float, float]:
    """The page pixel of survey point ``(x, y)``: the map's scale and offset measured through the readout (the
    readout adds the map's local origin back, so this also checks what a click at that pixel means)."""
    ax, ay, ea, na, m_per_px = map_scale(page)
    return ax + (x - ea) / m_per_px, ay + (na - y) / m_per_px


def metres_per_pixel(page: Page) -> float:
    """The map's scale, measured through the readout."""
    return map_scale(page)[4]


def plain_map_at(page: Page, px: float, py: float) -> bool:
    """Whether a click at ``(px, py)`` lands on the map itself (not a legend, layer list or map button)."""
    return bool(
        page.evaluate(
            """([x, y]) => {
                const e = document.elementFromPoint(x, y);
                return !!e && !!e.closest('[data-testid=map]') && !e.closest('.ol-control, .overlay-box');
            }""",
            [px, py],
        )
    )


def layer_lines(server: Server, layer: str) -> list[NDArray[np.float64]]:
    """Every polyline of a survey layer, unsimplified, as (N, 2) survey metres."""
    answer = server.api("GET", "/api/sites/1/survey/layers", params={"tolerance_m": 0, "layers": layer})
    assert answer.status_code == 200, answer.text
    lines: list[NDArray[np.float64]] = []

    def walk(coordinates: Any) -> None:
        if coordinates and isinstance(coordinates[0], (int, float)):
            raise AssertionError("a bare point in a line layer")
        if coordinates and isinstance(coordinates[0][0], (int, float)):
            lines.append(np.asarray(coordinates, dtype=np.float64)[:, :2])
        else:
            for c in coordinates:
                walk(c)

    for feature in answer.json()["layers"][layer]["features"]:
        walk(feature["geometry"]["coordinates"])
    assert lines, f"no {layer} lines"
    return lines


def distance_to_lines(point: tuple[float, float], lines: list[NDArray[np.float64]]) -> float:
    """Distance, metres, from a point to the nearest segment of any polyline."""
    p = np.asarray(point, dtype=np.float64)
    best = math.inf
    for line in lines:
        a, b = line[:-1], line[1:]
        ab = b - a
        u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
        best = min(best, float(np.min(np.hypot(*(a + u[:, None] * ab - p).T))))
    return best


def inside_walls(point: tuple[float, float], rings: list[NDArray[np.float64]]) -> bool:
    """Whether a point lies in the tunnels: inside an odd number of wall rings (the outline, not a pillar)."""
    x, y = point
    crossings = 0
    for ring in rings:
        a, b = ring, np.roll(ring, -1, axis=0)
        straddles = (a[:, 1] > y) != (b[:, 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            at_x = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
        crossings += int(np.count_nonzero(straddles & (x < at_x)))
    return crossings % 2 == 1
