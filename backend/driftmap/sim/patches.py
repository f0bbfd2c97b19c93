"""Procedural wall pictures (signs, stripes, doors, the dump and drawpoint faces) in strip texels.

Each function returns ``(img, alpha)`` float32 arrays, rows top-down as seen by a viewer, sized in
4 cm strip texels (:data:`driftmap.sim.strip.TEXEL_M`). Text is drawn with OpenCV's Hershey font at 8x
and area-averaged down, which is deterministic.
"""

from __future__ import annotations

import cv2
import numpy as np

from driftmap.sim.strip import TEXEL_M
from driftmap.sim.textures import F32, periodic_noise

__all__ = ["door_face", "dump_face", "hazard_stripes", "muck_face", "reflector", "survey_mark", "text_sign"]

_UP = 8  # supersampling of drawn pictures


def _px(m: float) -> int:
    return max(round(m / TEXEL_M), 1)


def _put_text(
    canvas: F32,
    text: str,
    org: tuple[int, int],
    scale: float,
    value: float,
    thick: int,
    font: int = cv2.FONT_HERSHEY_DUPLEX,
) -> None:
    """Draw ``text`` into a float canvas (OpenCV draws text on 8-bit images only)."""
    mask = np.zeros(canvas.shape, np.uint8)
    cv2.putText(mask, text, org, font, scale, 255, thick, cv2.LINE_AA)
    a = mask.astype(np.float32) / 255.0
    canvas *= 1.0 - a
    canvas += a * value


def _down(canvas: F32, h: int, w: int) -> F32:
    return np.asarray(cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA), dtype=np.float32)


def text_sign(
    lines: list[str], w_m: float, h_m: float, bg: float = 1.25, ink: float = 0.06, arrow: int = 0
) -> tuple[F32, F32]:
    """A reflective sign: border, centred text lines and optionally a chevron arrow (-1 left, +1 right)."""
    h, w = _px(h_m), _px(w_m)
    H, W = h * _UP, w * _UP
    c = np.full((H, W), bg, np.float32)
    cv2.rectangle(c, (0, 0), (W - 1, H - 1), ink, thickness=max(_UP, W // 40))
    text_h = H * (0.62 if arrow == 0 else 0.45)
    for k, line in enumerate(lines):
        if not line:
            continue
        (tw, th), _ = cv2.getTextSize(line, cv2.FONT_HERSHEY_DUPLEX, 1.0, 2)
        scale = min(0.82 * W / tw, text_h / len(lines) / th * 0.8)
        thick = max(int(scale * 2.2), 1)
        (tw, th), _ = cv2.getTextSize(line, cv2.FONT_HERSHEY_DUPLEX, scale, thick)
        y = int((k + 0.5) * text_h / len(lines) + th / 2 + 0.08 * H)
        _put_text(c, line, ((W - tw) // 2, y), scale, ink, thick)
    if arrow:
        y0, y1 = int(0.62 * H), int(0.9 * H)
        for k in range(3):
            x = int(W * (0.3 + 0.18 * k))
            tip = x + arrow * int(0.12 * W)
            pts = np.array([[x, y0], [tip, (y0 + y1) // 2], [x, y1]], np.int32)
            cv2.polylines(c, [pts], False, ink, thickness=max(W // 25, 2))
    return _down(c, h, w), np.ones((h, w), np.float32)


def hazard_stripes(w_m: float, h_m: float, period_m: float = 0.3, bright: float = 1.1) -> tuple[F32, F32]:
    """Diagonal black and yellow (bright) stripes, e.g. a painted brow or a stop block."""
    h, w = _px(h_m), _px(w_m)
    yy, xx = np.mgrid[0 : h * _UP, 0 : w * _UP].astype(np.float32) * (TEXEL_M / _UP)
    band = ((xx + yy) / period_m) % 1.0 < 0.5
    c = np.where(band, bright, 0.07).astype(np.float32)
    return _down(c, h, w), np.ones((h, w), np.float32)


def reflector(bright: float = 1.55) -> tuple[F32, F32]:
    """A small retro-reflective delineator plate (0.16 x 0.32 m) with a dark bar."""
    img = np.full((_px(0.32), _px(0.16)), bright, np.float32)
    img[img.shape[0] // 2 - 1 : img.shape[0] // 2 + 1, :] = 0.1
    return img, np.ones_like(img)


def survey_mark(label: str) -> tuple[F32, F32]:
    """Spray-painted survey station: a ring with a cross and a number, on a transparent background."""
    h, w = _px(0.6), _px(0.9)
    H, W = h * _UP, w * _UP
    c = np.zeros((H, W), np.float32)
    a = np.zeros((H, W), np.float32)
    r = H // 4
    cx, cy = W // 4, H // 2
    for img, val in ((c, 1.2), (a, 1.0)):
        cv2.circle(img, (cx, cy), r, val, thickness=_UP * 2)
        cv2.line(img, (cx - r, cy), (cx + r, cy), val, thickness=_UP)
        cv2.line(img, (cx, cy - r), (cx, cy + r), val, thickness=_UP)
        _put_text(img, label, (W // 2, cy + H // 8), H / 70.0, val, _UP * 2, cv2.FONT_HERSHEY_SIMPLEX)
    return _down(c, h, w), np.clip(_down(a, h, w), 0.0, 1.0)


def door_face(w_m: float, h_m: float, rng: np.random.Generator) -> tuple[F32, F32]:
    """A ventilation wall of concrete blocks with a steel door, a louvre regulator and a sign."""
    h, w = _px(h_m), _px(w_m)
    H, W = h * _UP, w * _UP
    c = (0.62 + 0.05 * periodic_noise(rng, H, W, 1.5)).astype(np.float32)
    block_h, block_w = int(0.2 / TEXEL_M * _UP), int(0.4 / TEXEL_M * _UP)
    for r, y in enumerate(range(0, H, block_h)):
        cv2.line(c, (0, y), (W, y), 0.35, _UP)
        for x in range((r % 2) * block_w // 2, W, block_w):
            cv2.line(c, (x, y), (x, y + block_h), 0.35, _UP)
    dw, dh = int(1.8 / TEXEL_M * _UP), int(2.4 / TEXEL_M * _UP)
    x0, y1 = W // 2 - dw // 2 - W // 8, H
    cv2.rectangle(c, (x0, y1 - dh), (x0 + dw, y1), 0.12, -1)
    cv2.rectangle(c, (x0, y1 - dh), (x0 + dw, y1), 1.2, 2 * _UP)
    cv2.circle(c, (x0 + dw - 3 * _UP * 2, y1 - dh // 2), 2 * _UP, 1.0, -1)
    lx0, lw, lh = x0 + dw + W // 10, int(1.2 / TEXEL_M * _UP), int(1.0 / TEXEL_M * _UP)
    ly0 = H - int(2.6 / TEXEL_M * _UP)
    cv2.rectangle(c, (lx0, ly0), (lx0 + lw, ly0 + lh), 0.08, -1)
    for y in range(ly0, ly0 + lh, 2 * _UP * 2):
        cv2.line(c, (lx0, y), (lx0 + lw, y), 0.7, _UP)
    sign, _ = text_sign(["VENT", "DOOR"], 1.0, 0.6)
    out = _down(c, h, w)
    sy, sx = h - _px(3.4), (x0 // _UP) + _px(0.4)
    out[sy : sy + sign.shape[0], sx : sx + sign.shape[1]] = sign
    return out, np.ones((h, w), np.float32)


def dump_face(w_m: float, h_m: float) -> tuple[F32, F32]:
    """The tip: a striped stop block below a dark ore-pass opening with grizzly bars."""
    h, w = _px(h_m), _px(w_m)
    img = np.full((h, w), 0.55, np.float32)
    stop, _ = hazard_stripes(w_m, 1.2, period_m=0.5)
    img[h - stop.shape[0] :, :] = stop
    hole_top, hole_bot = h - _px(4.2), h - _px(1.3)
    img[hole_top:hole_bot, _px(0.4) : w - _px(0.4)] = 0.03
    for x in range(_px(0.6), w - _px(0.4), _px(0.45)):
        img[hole_top:hole_bot, x : x + 2] = 0.7
    return img, np.ones((h, w), np.float32)


def muck_face(w_m: float, h_m: float, rng: np.random.Generator) -> tuple[F32, F32]:
    """Broken ore at a drawpoint face: dark, lumpy, brighter near the floor where it was dug."""
    h, w = _px(h_m), _px(w_m)
    lumps = periodic_noise(rng, h, w, 1.0)
    z = np.linspace(1.0, 0.0, h, dtype=np.float32)[:, None]
    img = (0.22 + 0.12 * np.tanh(lumps) + 0.12 * (1.0 - z)).astype(np.float32)
    return img, np.ones((h, w), np.float32)
