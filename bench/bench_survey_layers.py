"""Benchmark: survey-plan layers served per zoom level (``GET /api/sites/{id}/survey/layers?zoom=``).

A synthetic big plan: tunnel walls of a grid of drifts 2 km x 2 km, digitised every 0.2 m with survey noise
(~100,000 vertices per layer, like a plan traced from a laser scan), plus a centreline layer. For zoom levels
0-14 it prints the tolerance, the vertices served, the JSON size, the first (simplifying) call and a cached
call. Baseline, in the same process: serving the stored plan as it is (tolerance 0), which a map view would
otherwise download and draw at every zoom.
"""

from __future__ import annotations

import json
import statistics
import time
from typing import Any

import numpy as np

from driftmap.services import survey_layers
from driftmap.store.models import SurveyMap

SIDE_M = 2000.0
SPACING_M = 100.0
STEP_M = 0.2
WIDTH_M = 5.0
NOISE_M = 0.03
RUNS = 5


def _line(a: tuple[float, float], b: tuple[float, float], rng: np.random.Generator) -> list[list[float]]:
    n = max(2, int(np.hypot(b[0] - a[0], b[1] - a[1]) / STEP_M))
    t = np.linspace(0.0, 1.0, n)
    xy = np.c_[a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])] + rng.normal(0.0, NOISE_M, (n, 2))
    return [[round(float(x), 3), round(float(y), 3)] for x, y in xy]


def _collection(lines: list[list[list[float]]]) -> dict[str, Any]:
    features = [
        {
            "type": "Feature",
            "properties": {"entity": "LWPOLYLINE"},
            "geometry": {"type": "LineString", "coordinates": c},
        }
        for c in lines
    ]
    return {"type": "FeatureCollection", "features": features}


def big_plan() -> SurveyMap:
    """An unsaved SurveyMap row holding the synthetic plan (the service only reads its fields)."""
    rng = np.random.default_rng(7)
    walls, centre = [], []
    for k in np.arange(0.0, SIDE_M + 1, SPACING_M * 4):
        for offset in (-WIDTH_M / 2, WIDTH_M / 2):
            walls.append(_line((0.0, k + offset), (SIDE_M, k + offset), rng))
            walls.append(_line((k + offset, 0.0), (k + offset, SIDE_M), rng))
        centre.append(_line((0.0, k), (SIDE_M, k), rng))
        centre.append(_line((k, 0.0), (k, SIDE_M), rng))
    layers = {"WALLS": _collection(walls), "CENTRELINE": _collection(centre)}
    return SurveyMap(
        id=1,
        site_id=1,
        filename="big.dxf",
        dxf_sha256="b" * 64,
        units="m",
        min_x_m=-WIDTH_M,
        min_y_m=-WIDTH_M,
        max_x_m=SIDE_M + WIDTH_M,
        max_y_m=SIDE_M + WIDTH_M,
        layers=layers,
    )


def _timed(fn: Any) -> tuple[float, Any]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def main() -> None:
    plan = big_plan()
    full_s, full = _timed(lambda: survey_layers.survey_layers(plan))
    full_bytes = len(json.dumps(full["layers"]))
    print(f"plan: {full['vertices']:,} vertices, {full_bytes / 1e6:.1f} MB of GeoJSON as stored")
    print(
        f"{'zoom':>4} {'tol m':>8} {'vertices':>10} {'MB':>7} {'x smaller':>9} {'first s':>8} {'cached ms':>9}"
    )
    for zoom in (0, 2, 4, 6, 8, 10, 12, 14):
        tolerance = survey_layers.tolerance_for_zoom(plan, zoom)
        first_s, page = _timed(lambda t=tolerance: survey_layers.survey_layers(plan, tolerance_m=t))
        cached = [
            _timed(lambda t=tolerance: survey_layers.survey_layers(plan, tolerance_m=t))[0]
            for _ in range(RUNS)
        ]
        size = len(json.dumps(page["layers"]))
        print(
            f"{zoom:>4} {tolerance:>8.3f} {page['vertices']:>10,} {size / 1e6:>7.2f} {full_bytes / size:>9.1f}"
            f" {first_s:>8.2f} {1000 * statistics.median(cached):>9.3f}"
        )
    print(
        f"baseline (stored plan, tolerance 0): {full['vertices']:,} vertices at every zoom, first call {full_s:.2f} s"
    )


if __name__ == "__main__":
    main()
