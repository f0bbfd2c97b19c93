"""A map version as a DXF drawing for mine-planning packages (``docs/formats.md``).

The drawing is in the survey plan's own coordinates: site plane (mine-grid) metres, x east, y north,
``$INSUNITS`` 6 (metres), ASCII DXF R2010, so it overlays the plan it was grounded on (and reads back as a
survey plan). Each trajectory is one LWPOLYLINE on a layer of its own, ``DRIVE-<name>``; the topological
nodes and the loop closures are optional layers.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from ezdxf.filemanagement import new as new_dxf

from driftmap.formats.trajectory_exports import Track

NODES_LAYER = "NODES"
"""A POINT and a TEXT label (the node number) at each node centre, a LINE per topological edge."""
CLOSURES_LAYER = "CLOSURES"
"""A LINE between the two frames of each loop closure the optimiser kept."""
REJECTED_CLOSURES_LAYER = "CLOSURES-REJECTED"
"""A LINE between the two frames of each loop closure the optimiser rejected."""
LABEL_HEIGHT_M = 0.5  # text height of the node labels, metres
_NOT_IN_LAYER_NAMES = re.compile(r"[<>/\\\":;?*|=`'\x00-\x1f]")
_TRACK_COLOURS = (1, 3, 5, 6, 4, 2)  # AutoCAD colour index per drive layer, in turn


@dataclass(frozen=True)
class NodeMarks:
    """The topological map: ``centres_m`` (M, 2) node centres [x, y] (metres, node i at row i) and
    ``edges`` (E, 2) pairs of node numbers."""

    centres_m: Sequence[tuple[float, float]]
    edges: Sequence[tuple[int, int]]


@dataclass(frozen=True)
class ClosureSegment:
    """A loop closure drawn from the pose of frame a to the pose of frame b, site plane metres."""

    a_xy_m: tuple[float, float]
    b_xy_m: tuple[float, float]
    accepted: bool


def layer_name(kind: str, name: str, taken: set[str]) -> str:
    """A DXF layer name ``<KIND>-<name>`` with the characters DXF forbids as ``_``, unique (case-blind)
    among ``taken`` (which it joins)."""
    base = _NOT_IN_LAYER_NAMES.sub("_", f"{kind.upper()}-{name}")[:200]
    candidate, n = base, 1
    while candidate.upper() in taken:
        n += 1
        candidate = f"{base}-{n}"
    taken.add(candidate.upper())
    return candidate


def _finite(*values: float) -> tuple[float, ...]:
    for v in values:
        if not math.isfinite(v):
            raise ValueError(f"coordinate {v!r} is not finite")
    return values


def map_dxf_text(
    tracks: Sequence[Track],
    nodes: NodeMarks | None = None,
    closures: Sequence[ClosureSegment] | None = None,
) -> str:
    """The DXF drawing of ``tracks`` with optional node and closure layers, as ASCII DXF text.

    Args:
        tracks: trajectories in the site plane (metres); each becomes an LWPOLYLINE (a POINT when it has
            one pose) on layer ``<KIND>-<name>`` (e.g. ``DRIVE-map-01``), in order.
        nodes: when given, layer ``NODES``.
        closures: when given, layers ``CLOSURES`` (accepted) and ``CLOSURES-REJECTED``.

    Returns:
        The whole file as text (``\\n`` line ends).
    """
    doc = new_dxf("R2010")
    doc.header["$INSUNITS"] = 6
    msp = doc.modelspace()
    taken: set[str] = set()
    for k, track in enumerate(tracks):
        if not track.poses:
            continue
        layer = layer_name(track.kind, track.name, taken)
        doc.layers.add(layer, color=_TRACK_COLOURS[k % len(_TRACK_COLOURS)])
        points = [_finite(p.x_m, p.y_m) for p in track.poses]
        if len(points) == 1:
            msp.add_point(points[0], dxfattribs={"layer": layer})
        else:
            msp.add_lwpolyline(points, dxfattribs={"layer": layer})
    if nodes is not None:
        doc.layers.add(NODES_LAYER, color=7)
        for number, (x, y) in enumerate(nodes.centres_m):
            xy = _finite(x, y)
            msp.add_point(xy, dxfattribs={"layer": NODES_LAYER})
            label = msp.add_text(str(number), height=LABEL_HEIGHT_M, dxfattribs={"layer": NODES_LAYER})
            label.set_placement(xy)
        for a, b in nodes.edges:
            msp.add_line(nodes.centres_m[a], nodes.centres_m[b], dxfattribs={"layer": NODES_LAYER})
    if closures is not None:
        doc.layers.add(CLOSURES_LAYER, color=2)
        doc.layers.add(REJECTED_CLOSURES_LAYER, color=8)
        for c in closures:
            layer = CLOSURES_LAYER if c.accepted else REJECTED_CLOSURES_LAYER
            msp.add_line(_finite(*c.a_xy_m), _finite(*c.b_xy_m), dxfattribs={"layer": layer})
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue()
