"""Where things are in the synthetic mine: wall materials, signs, services, lights, puddles.

Decoration is tied to the centreline graph: each short piece of wall is matched to its nearest tunnel
edge (which edge, how far along it, on which side), and features are placed in edge terms -- a sign
9 m before every junction on the approaching driver's right, name plates and painted brows at every
drawpoint, a door at the access end, lights along drives. Long drives get visually aliased stretches:
a periodic wall template, evenly spaced lights and nothing unique. Everything is in mine-grid metres
except the strip, which is indexed by wall arc length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from driftmap.sim import patches
from driftmap.sim.geometry import FloatArray, heading_at, point_at
from driftmap.sim.layout import Edge, Layout
from driftmap.sim.strip import TEXEL_M, Patch, StripAtlas, StripBuilder
from driftmap.sim.textures import F32

__all__ = ["Decor", "WallPieces", "decorate"]

_PIECE_M = 1.0  # wall pieces matched to edges
_SIGN_TEXTS = (
    ["SPEED", "20"],
    ["REFUGE", "->"],
    ["NO", "ENTRY"],
    ["FIRST", "AID"],
    ["DANGER"],
    ["LEVEL", "5"],
    ["CH", "0+120"],
    ["PHONE"],
    ["FIRE", "EXT"],
    ["STOP"],
    ["GIVE", "WAY"],
    ["ORE", "PASS"],
)


@dataclass(frozen=True, eq=False)
class WallPieces:
    """Short pieces of the wall rings matched to edges; arrays are (N,) unless noted."""

    s0: FloatArray  # arc length of each piece's start on the strip
    s1: FloatArray  # arc length of its end
    mid: FloatArray  # (N, 2) grid metres
    edge: np.ndarray  # index of the nearest edge
    t: FloatArray  # arc length along that edge of the nearest centreline point
    side: np.ndarray  # +1 left of the edge direction, -1 right
    dist: FloatArray  # distance to the centreline


@dataclass(frozen=True, eq=False)
class Decor:
    """What decoration produced: the strip and grid-metre feature tables."""

    strip: StripAtlas
    lights: FloatArray  # (K, 3): x, y, heading of roof light tubes
    spots: FloatArray  # (K, 5): x, y, radius, albedo gain, paint albedo (0: none) of floor patches
    roof_marks: FloatArray  # (K, 6): x, y, heading, half length, half width, albedo of painted roof bands
    aliased: dict[int, tuple[float, float]]  # edge id -> (t0, t1) aliased stretch


def _pieces(layout: Layout, seg_p0: FloatArray, seg_p1: FloatArray, seg_s0: FloatArray) -> WallPieces:
    lengths = np.hypot(*(seg_p1 - seg_p0).T)
    s0s, s1s, mids = [], [], []
    for a, b, s, length in zip(seg_p0, seg_p1, seg_s0, lengths, strict=True):
        n = max(math.ceil(length / _PIECE_M), 1)
        f = np.linspace(0.0, 1.0, n + 1)
        s0s.append(s + f[:-1] * length)
        s1s.append(s + f[1:] * length)
        mids.append(a + ((f[:-1] + f[1:]) / 2)[:, None] * (b - a))
    mid = np.concatenate(mids)
    best = np.full(len(mid), np.inf)
    edge = np.zeros(len(mid), np.int64)
    t = np.zeros(len(mid))
    side = np.ones(len(mid), np.int64)
    for e in layout.edges:
        a, b = e.polyline[:-1], e.polyline[1:]
        d = b - a
        L2 = np.maximum(np.sum(d * d, axis=1), 1e-12)
        rel = mid[:, None, :] - a[None]
        u = np.clip(np.sum(rel * d[None], axis=2) / L2, 0.0, 1.0)
        q = a[None] + u[..., None] * d[None]
        dist = np.hypot(*(mid[:, None, :] - q).transpose(2, 0, 1))
        k = np.argmin(dist, axis=1)
        dk = dist[np.arange(len(mid)), k]
        better = dk < best
        cum = np.concatenate([[0.0], np.cumsum(np.sqrt(L2))])
        cross = d[k, 0] * rel[np.arange(len(mid)), k, 1] - d[k, 1] * rel[np.arange(len(mid)), k, 0]
        best = np.where(better, dk, best)
        edge = np.where(better, e.id, edge)
        t = np.where(better, cum[k] + u[np.arange(len(mid)), k] * np.sqrt(L2[k]), t)
        side = np.where(better, np.where(cross >= 0, 1, -1), side)
    return WallPieces(np.concatenate(s0s), np.concatenate(s1s), mid, edge, t, side, best)


def _wall_s(p: WallPieces, edge: Edge, t_m: float, side: int) -> float | None:
    """Strip arc length of the wall on ``side`` of ``edge`` at ``t_m`` along it, None if not found."""
    sel = np.flatnonzero((p.edge == edge.id) & (p.side == side) & (p.dist > edge.width_m / 2 - 0.6))
    if sel.size == 0:
        return None
    i = sel[np.argmin(np.abs(p.t[sel] - t_m))]
    if abs(p.t[i] - t_m) > 1.5:
        return None
    return float((p.s0[i] + p.s1[i]) / 2)


def decorate(
    layout: Layout,
    seg_p0: FloatArray,
    seg_p1: FloatArray,
    seg_s0: FloatArray,
    total_s_m: float,
    rng: np.random.Generator,
) -> Decor:
    """Place every decoration of the site.

    Args:
        layout: the level.
        seg_p0, seg_p1: (M, 2) wall segments in grid metres, in ring order.
        seg_s0: (M,) strip arc length at each segment start.
        total_s_m: strip length.
        rng: source of randomness (the site seed's decoration stream).
    """
    p = _pieces(layout, seg_p0, seg_p1, seg_s0)
    sb = StripBuilder(total_s_m, rng)
    aliased: dict[int, tuple[float, float]] = {}
    for e in layout.edges:
        if e.kind == "drive" and e.length_m >= 45.0 and rng.random() < 0.75:
            aliased[e.id] = (14.0, e.length_m - 14.0)
    _materials_and_services(layout, p, sb, aliased, rng)
    _signs(layout, p, sb, rng)
    _marks(layout, p, sb, aliased, rng)
    _faces(layout, p, sb, rng)
    lights, spots, marks = _roof_and_floor(layout, aliased, rng)
    return Decor(sb.build(), lights, spots, marks, aliased)


def _paste(sb: StripBuilder, picture: tuple[F32, F32], s_center_m: float, z_m: float) -> None:
    img, alpha = picture
    sb.patches.append(Patch(s_center_m + img.shape[1] * TEXEL_M / 2, z_m, img, alpha))


def _materials_and_services(
    layout: Layout,
    p: WallPieces,
    sb: StripBuilder,
    aliased: dict[int, tuple[float, float]],
    rng: np.random.Generator,
) -> None:
    """Runs of rock and shotcrete along the strip; cables on drives, vent ducts in production tunnels;
    the periodic template in aliased stretches."""
    s = 0.0
    while s < sb.total_m:
        run = float(rng.uniform(4.0, 25.0))
        sb.brightness[sb.cols(s, s + run)] = rng.choice([0.30, 0.36, 0.46, 0.55])
        s += run
    for i in range(len(p.s0)):
        e = layout.edges[int(p.edge[i])]
        cols = sb.cols(p.s0[i], p.s1[i])
        if e.id in aliased and aliased[e.id][0] <= p.t[i] <= aliased[e.id][1]:
            sb.aliased[cols] = True
            sb.brightness[cols] = 0.45
        if e.kind in ("drive", "access") and p.side[i] > 0 and 1.5 < p.t[i] < e.length_m - 1.5:
            sb.cable[cols] = True
        if e.kind in ("production", "access") and p.side[i] < 0 and 3.0 < p.t[i] < e.length_m - 3.0:
            sb.duct[cols] = True


def _signs(layout: Layout, p: WallPieces, sb: StripBuilder, rng: np.random.Generator) -> None:
    """Junction signs on the approaching driver's right, drawpoint brows and name plates, DUMP signs."""
    for e in layout.edges:
        for end, t, side in ((e.b, e.length_m - 9.0, -1), (e.a, 9.0, 1)):
            node = layout.nodes[end]
            if node.kind != "junction" or e.kind == "drawpoint" or e.length_m < 16.0:
                continue
            ws = _wall_s(p, e, t, side)
            if ws is not None:
                arrow = int(rng.choice([-1, 1]))
                _paste(sb, patches.text_sign([node.name], 1.0, 0.6, arrow=arrow), ws, 2.1)
        if e.kind == "drawpoint":
            for side in (1, -1):
                ws = _wall_s(p, e, 3.0, side)
                if ws is not None:
                    _paste(sb, patches.hazard_stripes(0.6, 5.0), ws, 0.0)
                    _paste(sb, patches.text_sign([layout.nodes[e.b].name], 0.9, 0.5), ws - side * 1.0, 2.3)
        if e.kind == "dump":
            for side in (1, -1):
                ws = _wall_s(p, e, 4.0, side)
                if ws is not None:
                    _paste(sb, patches.text_sign(["DUMP"], 1.6, 0.7, bg=1.3), ws, 2.4)


def _marks(
    layout: Layout,
    p: WallPieces,
    sb: StripBuilder,
    aliased: dict[int, tuple[float, float]],
    rng: np.random.Generator,
) -> None:
    """Random signs and survey marks, and reflectors every 12 m on drives, outside aliased stretches."""
    survey = 1
    for e in layout.edges:
        if e.kind == "drawpoint":
            continue
        a0, a1 = aliased.get(e.id, (np.inf, -np.inf))
        for side in (1, -1):
            t = float(rng.uniform(5.0, 40.0))
            while t < e.length_m - 5.0:
                ws = _wall_s(p, e, t, side)
                if ws is not None and not a0 <= t <= a1:
                    if rng.random() < 0.45:
                        text = _SIGN_TEXTS[int(rng.integers(len(_SIGN_TEXTS)))]
                        _paste(sb, patches.text_sign(list(text), 0.9, 0.6), ws, float(rng.uniform(1.8, 2.6)))
                    else:
                        _paste(sb, patches.survey_mark(f"{survey}"), ws, float(rng.uniform(1.3, 1.9)))
                        survey += 1
                t += float(rng.uniform(18.0, 45.0))
            if e.kind in ("drive", "access"):
                for t in np.arange(6.0, e.length_m - 3.0, 12.0):
                    ws = _wall_s(p, e, float(t), side)
                    if ws is not None and not a0 <= t <= a1:
                        _paste(sb, patches.reflector(), ws, 1.25)


def _faces(layout: Layout, p: WallPieces, sb: StripBuilder, rng: np.random.Generator) -> None:
    """Pictures on the dead-end faces: muck at drawpoints, the tip at the dump, a door at the access."""
    for e in layout.edges:
        leaf = layout.nodes[e.b]
        if leaf.kind == "junction":
            continue
        sel = np.flatnonzero((p.edge == e.id) & (p.t > e.length_m - 0.05))
        if sel.size == 0:
            continue
        s0, s1 = float(p.s0[sel].min()), float(p.s1[sel].max())
        width = s1 - s0
        if leaf.kind == "drawpoint":
            img, alpha = patches.muck_face(width, 5.0, rng)
        elif leaf.kind == "dump":
            img, alpha = patches.dump_face(width, 5.0)
        else:
            img, alpha = patches.door_face(width, 5.0, rng)
        sb.patches.append(Patch(s1, 0.0, img, alpha))


def _roof_and_floor(
    layout: Layout, aliased: dict[int, tuple[float, float]], rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, FloatArray]:
    lights: list[list[float]] = []
    spots: list[list[float]] = []
    marks: list[list[float]] = []
    for e in layout.edges:
        L = e.length_m
        a0, a1 = aliased.get(e.id, (np.inf, -np.inf))
        if e.kind in ("drive", "access"):
            ts = [float(t) for t in np.arange(12.0, L - 6.0, 27.0) if not a0 <= t <= a1]
            ts += [float(t) for t in np.arange(a0, a1, 30.0)] if e.id in aliased else []
        elif e.kind == "production":
            ts = [4.0, L - 4.0] if L > 12 else [L / 2]
        elif e.kind == "dump":
            ts = [L / 2]
        else:
            ts = []
        for t in ts:
            xy = point_at(e.polyline, t)
            lights.append([xy[0], xy[1], heading_at(e.polyline, t)])
        if e.kind == "drawpoint":
            xy = point_at(e.polyline, 2.5)
            marks.append([xy[0], xy[1], heading_at(e.polyline, 2.5) + math.pi / 2, e.width_m / 2, 0.25, 1.2])
        t = float(rng.uniform(5.0, 40.0))
        while t < L - 3.0:
            if not a0 <= t <= a1:
                xy = point_at(e.polyline, t)
                h = heading_at(e.polyline, t)
                off = float(rng.uniform(-1.2, 1.2))
                xy = xy + off * np.array([-math.sin(h), math.cos(h)])
                spots.append([xy[0], xy[1], float(rng.uniform(0.6, 1.8)), float(rng.uniform(0.35, 0.6)), 0.0])
            t += float(rng.uniform(15.0, 50.0))
    return (
        np.asarray(lights, np.float64).reshape(-1, 3),
        np.asarray(spots, np.float64).reshape(-1, 5),
        np.asarray(marks, np.float64).reshape(-1, 6),
    )
