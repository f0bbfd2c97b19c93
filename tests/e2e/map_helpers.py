"""Where things are on the map in the browser: the survey point under a page pixel (read from the grid readout)
and back, and whether a pixel is plain map (no legend, layer list or map button over it)."""

from __future__ import annotations

import math
import re
import time

from playwright.sync_api import Page

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


def _scale(page: Page) -> tuple[float, float, float, float, float]:
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
    ax, ay, ea, na, m_per_px = _scale(page)
    return ax + (x - ea) / m_per_px, ay + (na - y) / m_per_px


def metres_per_pixel(page: Page) -> float:
    """The map's scale, measured through the readout."""
    return _scale(page)[4]


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
