"""The surveyed mine map of a synthetic site as a DXF (``docs/formats.md``: site survey map).

Layers: WALLS (closed LWPOLYLINE per wall ring), CENTRELINE (LWPOLYLINE per graph edge), DRAWPOINTS
(POINT and a 1 m CIRCLE at each drawpoint face and the dump), LABELS (TEXT: drawpoint names, DUMP,
ACCESS). R2010, $INSUNITS = 6 (metres), mine-grid coordinates. Output is byte-identical for the same
layout: ezdxf's time stamps and GUIDs are pinned while the document is created and written.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import ezdxf
from ezdxf.filemanagement import new as new_dxf

from driftmap.sim.layout import Layout

__all__ = ["LAYERS", "write_survey_dxf"]

_OPTIONS = ezdxf.options  # type: ignore[attr-defined]
LAYERS: dict[str, int] = {"WALLS": 7, "CENTRELINE": 1, "DRAWPOINTS": 3, "LABELS": 2}  # name -> ACI colour


@contextlib.contextmanager
def _fixed_metadata() -> Iterator[None]:
    """Pin ezdxf's creation/update dates and GUIDs so that the file depends only on its content."""
    saved = _OPTIONS.write_fixed_meta_data_for_testing
    _OPTIONS.write_fixed_meta_data_for_testing = True
    try:
        yield
    finally:
        _OPTIONS.write_fixed_meta_data_for_testing = saved


def write_survey_dxf(layout: Layout, path: Path) -> None:
    """Write the survey DXF of ``layout`` to ``path`` (grid metres, 3 decimals)."""
    with _fixed_metadata():
        doc = new_dxf("R2010", setup=False)
        doc.header["$INSUNITS"] = 6
        doc.header["$MEASUREMENT"] = 1
        for name, colour in LAYERS.items():
            doc.layers.add(name, color=colour)
        msp = doc.modelspace()
        for ring in layout.walls:
            pts = [(round(float(x), 3), round(float(y), 3)) for x, y in ring[:-1]]
            msp.add_lwpolyline(pts, close=True, dxfattribs={"layer": "WALLS"})
        for e in layout.edges:
            pts = [(round(float(x), 3), round(float(y), 3)) for x, y in e.polyline]
            msp.add_lwpolyline(pts, dxfattribs={"layer": "CENTRELINE"})
        for n in layout.nodes:
            if n.kind == "junction":
                continue
            xy = (round(n.xy[0], 3), round(n.xy[1], 3))
            if n.kind in ("drawpoint", "dump"):
                msp.add_point(xy, dxfattribs={"layer": "DRAWPOINTS"})
                msp.add_circle(xy, 1.0, dxfattribs={"layer": "DRAWPOINTS"})
            text = msp.add_text(n.name, height=1.5, dxfattribs={"layer": "LABELS"})
            text.set_placement((xy[0] + 1.5, xy[1] + 1.5))
        path.parent.mkdir(parents=True, exist_ok=True)
        doc.saveas(path)
