"""2-D pose-graph files: g2o (``VERTEX_SE2``, ``EDGE_SE2``, ``FIX``) and TORO (``VERTEX2``, ``EDGE2``).

These are the formats of the standard benchmarks in ``shared/data/posegraphs`` (M3500, Intel, city10000,
MIT Killian). A vertex is a pose [x, y, theta] (metres, radians) in the file's world frame; an edge
``i j dx dy dtheta`` is the measured pose of vertex j in vertex i with an information matrix given by its
upper triangle, in g2o order ``I11 I12 I13 I22 I23 I33`` or TORO order ``xx xy yy tt xt yt``. Every error
names the file, the 1-based line and the field at fault. :func:`to_pose_graph` turns a graph into the
odometry chains and loop closures of :mod:`driftmap.core.graph.posegraph`; :func:`g2o_text` writes a graph
back as g2o (the map export's pose graph).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from driftmap.core.graph.constraints import LoopConstraint, OdometryChain
from driftmap.errors import BadInputError

_VERTEX_FIELDS = ("id", "x", "y", "theta")
_EDGE_FIELDS = ("id_i", "id_j", "dx", "dy", "dtheta")
_G2O_INFO = ("I11", "I12", "I13", "I22", "I23", "I33")
_TORO_INFO = ("Ixx", "Ixy", "Iyy", "Itt", "Ixt", "Iyt")
_TORO_TO_G2O = (0, 1, 4, 2, 5, 3)  # TORO upper-triangle entries in g2o order
_NOT_2D = ("VERTEX_SE3:QUAT", "EDGE_SE3:QUAT", "VERTEX3", "EDGE3")
_LANDMARKS = ("VERTEX_XY", "EDGE_SE2_XY", "EDGE_SE2_POINTXY")


@dataclass(frozen=True, eq=False)
class G2oGraph:
    """A 2-D pose graph as read from a file; vertices sorted by id.

    Attributes:
        vertex_ids: (N,) int64 vertex ids, ascending.
        wTi: (N, 3) float64 vertex poses [x_m, y_m, theta_rad] in the file's world frame.
        edge_ij: (K, 2) int64 row indices into ``vertex_ids`` of each edge's (i, j), in file order.
        iTj: (K, 3) float64 measured pose of j in i, [dx_m, dy_m, dtheta_rad].
        information: (K, 3, 3) float64 symmetric positive-definite information, (x, y, theta) order.
        edge_lines: (K,) int64 1-based line of each edge.
        fixed: (F,) int64 row indices of vertices named by ``FIX`` lines.
    """

    vertex_ids: NDArray[np.int64]
    wTi: NDArray[np.float64]
    edge_ij: NDArray[np.int64]
    iTj: NDArray[np.float64]
    information: NDArray[np.float64]
    edge_lines: NDArray[np.int64]
    fixed: NDArray[np.int64]


def read_g2o(path: str | Path) -> G2oGraph:
    """Read a 2-D g2o or TORO pose-graph file; raises ``BadInputError`` naming file and line."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInputError(f"cannot read pose graph: {exc}", file=path) from None
    return parse_g2o(text, path)


def _id(token: str, file: str | Path, line: int, field: str) -> int:
    try:
        value = int(token)
    except ValueError:
        raise BadInputError(f"{token!r} is not a vertex id", file=file, line=line, field=field) from None
    if value < 0:
        raise BadInputError(f"vertex id {value} is negative", file=file, line=line, field=field)
    return value


def _numbers(tokens: list[str], fields: tuple[str, ...], file: str | Path, line: int) -> list[float]:
    values = []
    for token, field in zip(tokens, fields, strict=True):
        try:
            value = float(token)
        except ValueError:
            raise BadInputError(f"{token!r} is not a number", file=file, line=line, field=field) from None
        if not math.isfinite(value):
            raise BadInputError(f"{token!r} is not finite", file=file, line=line, field=field)
        values.append(value)
    return values


def parse_g2o(text: str, file: str | Path = "<g2o>") -> G2oGraph:
    """Parse the text of a 2-D g2o or TORO file; ``file`` names it in error messages.

    Blank lines and ``#`` comments are skipped; vertices may come after the edges that use them.
    """
    vertices: dict[int, tuple[int, list[float]]] = {}
    edges: list[tuple[int, int, int, list[float], NDArray[np.float64]]] = []
    fixed: list[tuple[int, int]] = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        tokens = raw.split("#", 1)[0].split()
        if not tokens:
            continue
        tag, args = tokens[0], tokens[1:]
        if tag in ("VERTEX_SE2", "VERTEX2"):
            if len(args) != 4:
                raise BadInputError(
                    f"{tag} needs 4 values (id x y theta), got {len(args)}", file=file, line=line_no
                )
            vid = _id(args[0], file, line_no, "id")
            if vid in vertices:
                raise BadInputError(
                    f"vertex {vid} defined twice (first on line {vertices[vid][0]})",
                    file=file,
                    line=line_no,
                    field="id",
                )
            vertices[vid] = (line_no, _numbers(args[1:], _VERTEX_FIELDS[1:], file, line_no))
        elif tag in ("EDGE_SE2", "EDGE2"):
            if len(args) != 11:
                raise BadInputError(
                    f"{tag} needs 11 values (i j dx dy dtheta + 6 information), got {len(args)}",
                    file=file,
                    line=line_no,
                )
            i, j = _id(args[0], file, line_no, "id_i"), _id(args[1], file, line_no, "id_j")
            if i == j:
                raise BadInputError(f"edge joins vertex {i} to itself", file=file, line=line_no, field="id_j")
            info_fields = _G2O_INFO if tag == "EDGE_SE2" else _TORO_INFO
            measured = _numbers(args[2:5], _EDGE_FIELDS[2:], file, line_no)
            upper = _numbers(args[5:], info_fields, file, line_no)
            if tag == "EDGE2":
                upper = [upper[k] for k in _TORO_TO_G2O]
            a, b, c, d, e, f = upper
            info = np.array([[a, b, c], [b, d, e], [c, e, f]])
            if np.linalg.eigvalsh(info).min() <= 0:
                raise BadInputError(
                    "information matrix is not positive definite",
                    file=file,
                    line=line_no,
                    field="information",
                )
            edges.append((line_no, i, j, measured, info))
        elif tag == "FIX":
            if not args:
                raise BadInputError("FIX needs at least one vertex id", file=file, line=line_no)
            fixed += [(line_no, _id(a, file, line_no, "id")) for a in args]
        elif tag in _NOT_2D:
            raise BadInputError(
                f"{tag} is a 3-D record; only 2-D pose graphs are read", file=file, line=line_no
            )
        elif tag in _LANDMARKS:
            raise BadInputError(
                f"{tag} is a landmark record; only pose graphs are read", file=file, line=line_no
            )
        else:
            raise BadInputError(f"unknown record type {tag!r}", file=file, line=line_no)
    if not vertices:
        raise BadInputError("no VERTEX_SE2 or VERTEX2 records", file=file)
    ids = np.array(sorted(vertices), dtype=np.int64)
    row = {int(v): r for r, v in enumerate(ids)}

    def index(vid: int, line: int, field: str) -> int:
        if vid not in row:
            raise BadInputError(f"vertex {vid} is not defined", file=file, line=line, field=field)
        return row[vid]

    return G2oGraph(
        vertex_ids=ids,
        wTi=np.array([vertices[int(v)][1] for v in ids], dtype=np.float64),
        edge_ij=np.array(
            [(index(i, ln, "id_i"), index(j, ln, "id_j")) for ln, i, j, _, _ in edges], dtype=np.int64
        ).reshape(-1, 2),
        iTj=np.array([m for *_, m, _ in edges], dtype=np.float64).reshape(-1, 3),
        information=np.array([info for *_, info in edges], dtype=np.float64).reshape(-1, 3, 3),
        edge_lines=np.array([e[0] for e in edges], dtype=np.int64),
        fixed=np.array([index(v, ln, "id") for ln, v in fixed], dtype=np.int64),
    )


def read_pose_table(path: str | Path) -> NDArray[np.float64]:
    """Read a ground-truth table of ``x y theta`` rows (one pose per line) as an (N, 3) float64 array."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInputError(f"cannot read poses: {exc}", file=path) from None
    rows = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        tokens = raw.split("#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) != 3:
            raise BadInputError(f"expected 3 values (x y theta), got {len(tokens)}", file=path, line=line_no)
        rows.append(_numbers(tokens, _VERTEX_FIELDS[1:], path, line_no))
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def to_pose_graph(graph: G2oGraph) -> tuple[list[OdometryChain], list[LoopConstraint]]:
    """Split a benchmark graph into odometry chains and loop closures for the pose-graph core.

    The first edge from vertex row r to row r+1 is odometry; where there is none the chain breaks, so the
    chains' frames are the vertex rows in order (``np.concatenate(result.wTi)`` lines up with ``wTi``).
    Every other edge is a loop closure, in file order. Vertex poses become the chains' initial poses and
    the information matrices are kept whole.

    Args:
        graph: as read by :func:`read_g2o`.

    Returns:
        (chains, closures).
    """
    num, ij = graph.wTi.shape[0], graph.edge_ij
    odometry = np.full(num - 1, -1, dtype=np.int64)
    for k in np.flatnonzero(ij[:, 1] == ij[:, 0] + 1)[::-1]:
        odometry[ij[k, 0]] = k  # walking backwards, the first edge of a pair wins
    starts = np.concatenate([[0], np.flatnonzero(odometry < 0) + 1, [num]])
    chain_of = np.searchsorted(starts, np.arange(num), side="right") - 1
    ref = [(int(chain_of[r]), int(r - starts[chain_of[r]])) for r in range(num)]
    ones = np.ones(3)  # sigmas are required but the information matrices rule
    chains = [
        OdometryChain(
            graph.iTj[odometry[a : b - 1]], ones, graph.information[odometry[a : b - 1]], graph.wTi[a:b]
        )
        for a, b in itertools.pairwise(starts)
    ]
    is_closure = np.ones(ij.shape[0], dtype=bool)
    is_closure[odometry[odometry >= 0]] = False
    closures = []
    for k in np.flatnonzero(is_closure):
        x, y, theta = (float(v) for v in graph.iTj[k])
        closures.append(
            LoopConstraint(
                ref[ij[k, 0]], ref[ij[k, 1]], (1.0, 1.0, 1.0), (x, y, theta), information=graph.information[k]
            )
        )
    return chains, closures


def relative_poses(wTi: NDArray[np.float64], edge_ij: NDArray[np.int64]) -> NDArray[np.float64]:
    """The pose of j in i for every edge: (K, 3) [dx_m, dy_m, dtheta_rad], dtheta wrapped to [-pi, pi).

    Args:
        wTi: (N, 3) poses [x_m, y_m, theta_rad] in one world frame.
        edge_ij: (K, 2) row indices (i, j) into ``wTi``.
    """
    wTi = np.asarray(wTi, dtype=np.float64).reshape(-1, 3)
    ij = np.asarray(edge_ij, dtype=np.int64).reshape(-1, 2)
    a, b = wTi[ij[:, 0]], wTi[ij[:, 1]]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    dtheta = (b[:, 2] - a[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return np.stack([c * dx + s * dy, -s * dx + c * dy, dtheta], axis=1)


def g2o_text(graph: G2oGraph, comments: Sequence[str] = ()) -> str:
    """The text of a 2-D g2o file that :func:`parse_g2o` reads back as ``graph``.

    One ``VERTEX_SE2 id x y theta`` per vertex, one ``EDGE_SE2 i j dx dy dtheta I11 I12 I13 I22 I23 I33``
    per edge (in ``graph`` order), one ``FIX`` line when vertices are fixed, then the ``#`` comment lines
    (last: GTSAM's ``readG2o`` stops reading edges at the first comment line). Numbers are written with
    :func:`repr` (read back identical).

    Raises:
        ValueError: a non-finite number (g2o readers refuse them).
    """
    if not (np.all(np.isfinite(graph.wTi)) and np.all(np.isfinite(graph.iTj))):
        raise ValueError("pose graph has non-finite poses or measurements")
    ids = graph.vertex_ids

    def numbers(values: NDArray[np.float64]) -> str:
        return " ".join(repr(float(v)) for v in values)

    lines = [f"VERTEX_SE2 {int(v)} {numbers(p)}" for v, p in zip(ids, graph.wTi, strict=True)]
    upper = np.triu_indices(3)
    for (i, j), measured, info in zip(graph.edge_ij, graph.iTj, graph.information, strict=True):
        lines.append(f"EDGE_SE2 {int(ids[i])} {int(ids[j])} {numbers(measured)} {numbers(info[upper])}")
    if graph.fixed.size:
        lines.append("FIX " + " ".join(str(int(ids[r])) for r in graph.fixed))
    lines += [f"# {c}" for c in comments]
    return "\n".join(lines) + "\n"
