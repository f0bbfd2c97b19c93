"""Drawing helpers shared by the reports: the survey plan as a backdrop, headless matplotlib."""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes

PLAN_STYLE = {"WALLS": ("#9a9a9a", 0.8), "CENTRELINE": ("#d0d0d0", 0.5), "DRAWPOINTS": ("#b08040", 0.8)}


def draw_plan(ax: Axes, layers: dict[str, Any], origin: tuple[float, float] = (0.0, 0.0)) -> None:
    """Draw the line features of a stored survey map (layer name -> FeatureCollection) in grey.

    Coordinates are shifted by ``origin`` (metres) so that mine-grid numbers stay readable.
    """
    for name, layer in layers.items():
        colour, width = PLAN_STYLE.get(name.upper(), ("#c8c8c8", 0.5))
        for feature in layer.get("features", []):
            geometry = feature.get("geometry") or {}
            if geometry.get("type") != "LineString":
                continue
            coords = geometry.get("coordinates") or []
            if len(coords) < 2:
                continue
            xs = [c[0] - origin[0] for c in coords]
            ys = [c[1] - origin[1] for c in coords]
            ax.plot(xs, ys, color=colour, linewidth=width, zorder=1)


def new_figure(cols: int, rows: int = 1, size_in: float = 5.0) -> tuple[Any, list[Axes]]:
    """A figure of ``cols`` x ``rows`` square-ish panels."""
    fig, axes = plt.subplots(rows, cols, figsize=(size_in * cols, size_in * rows), squeeze=False)
    return fig, [ax for row in axes for ax in row]


def save(fig: Any, path: str) -> None:
    """Write ``fig`` as a PNG and release it."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
