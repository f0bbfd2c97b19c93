"""A corpus of DXF survey plans in the shapes CAD programs write them, generated with ezdxf.

Each file is named ``<scenario>-<version>[-<variant>].dxf`` and knows whether driftmap should import or refuse
it: every DXF version ezdxf writes (R12 to R2018) in ASCII, a binary and a CR LF variant; every entity kind
the reader draws and some it leaves out; block references nested, rotated, mirrored and in grids; extrusion
(0, 0, -1); drawing units; empty, tiny, huge and far-from-origin drawings; and files damaged on the byte
level (truncated, garbage, encodings, malformed values for the recovery mode).
"""

from __future__ import annotations

import io
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ezdxf.document import Drawing
from ezdxf.filemanagement import new as new_dxf

VERSIONS = ("R12", "R2000", "R2004", "R2007", "R2010", "R2013", "R2018")
Scenario = Callable[[Drawing, Any, bool], None]  # (doc, model space, whether R2000 entities exist)


@dataclass(frozen=True)
class CorpusFile:
    """One plan of the corpus: its name, bytes and whether it should be imported."""

    name: str
    data: bytes
    importable: bool


def _lines(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_line((0, 0), (100, 0), dxfattribs={"layer": "WALLS"})
    msp.add_polyline2d([(0, 10), (40, 10), (40, 30)], close=True, dxfattribs={"layer": "OUTLINE"})
    msp.add_polyline3d([(0, 50, -200), (30, 60, -210), (60, 50, -220)], dxfattribs={"layer": "DECLINE"})
    if modern:
        msp.add_lwpolyline(
            [(0, 80, 0.5), (20, 80, 0), (20, 90, -1)], format="xyb", dxfattribs={"layer": "DRIFT"}
        )


def _curves(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_arc((50, 50), 20, 30, 300, dxfattribs={"layer": "ARCS"})
    msp.add_circle((10, 10), 3, dxfattribs={"layer": "SHAFTS"})
    if modern:
        msp.add_ellipse((80, 80), major_axis=(10, 5), ratio=0.3, start_param=0.5, end_param=4.0)
        msp.add_spline([(0, 0), (10, 20), (30, -5), (50, 10), (70, 0)], dxfattribs={"layer": "ROADS"})
        msp.add_open_spline([(0, 100), (10, 120), (20, 100), (30, 120)], degree=3)


def _hatches(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_line((0, 0), (1, 1))
    if not modern:
        return
    solid = msp.add_hatch(color=3, dxfattribs={"layer": "STOPES"})
    solid.paths.add_polyline_path([(0, 0, 0), (20, 0, 0.4), (20, 20, 0), (0, 20, 0)], is_closed=True)
    solid.paths.add_polyline_path([(5, 5), (8, 5), (8, 8)], is_closed=True)  # an island
    edges = msp.add_hatch(dxfattribs={"layer": "PILLARS"}).paths.add_edge_path()
    edges.add_line((30, 0), (40, 0))
    edges.add_arc((40, 5), 5, -90, 90)
    edges.add_ellipse((35, 10), major_axis=(5, 0), ratio=0.5, start_angle=0, end_angle=180)
    edges.add_spline(control_points=[(30, 10), (28, 5), (30, 0)], degree=2)
    pattern = msp.add_hatch(dxfattribs={"layer": "PATTERN"})
    pattern.set_pattern_fill("ANSI31", scale=0.5)
    pattern.paths.add_polyline_path([(50, 0), (60, 0), (60, 10), (50, 10)])


def _texts(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_text("DP 12", dxfattribs={"layer": "LABELS", "insert": (3, 4), "rotation": 30})
    msp.add_point((7, 8), dxfattribs={"layer": "STATIONS"})
    if modern:
        msp.add_mtext(
            "Level 3\\PDrive 7 {\\fArial|b1;bold}", dxfattribs={"layer": "LABELS", "insert": (9, 9)}
        )


def _blocks(doc: Drawing, msp: Any, modern: bool) -> None:
    drawpoint = doc.blocks.new("DRAWPOINT")
    drawpoint.add_line((0, 0), (1, 0))
    drawpoint.add_circle((0, 0), 0.5, dxfattribs={"layer": "RINGS"})
    drawpoint.add_attdef("NAME", (0, 1))
    pair = doc.blocks.new("PAIR")
    pair.add_blockref("DRAWPOINT", (0, 0))
    pair.add_blockref("DRAWPOINT", (5, 0), dxfattribs={"rotation": 180})
    ref = msp.add_blockref("DRAWPOINT", (100, 200), dxfattribs={"layer": "DP", "xscale": 2, "yscale": -2})
    ref.add_auto_attribs({"NAME": "DP-1"})
    msp.add_blockref("PAIR", (0, -50), dxfattribs={"layer": "PAIRS", "rotation": 45})
    msp.add_blockref("PAIR", (20, 20)).grid(size=(3, 4), spacing=(10, 10))


def _downward(doc: Drawing, msp: Any, modern: bool) -> None:
    down = {"extrusion": (0, 0, -1), "layer": "MIRRORED"}
    msp.add_arc((10, 10), 5, 0, 90, dxfattribs=down)
    msp.add_circle((20, 10), 2, dxfattribs=down)
    msp.add_text("under", dxfattribs={**down, "insert": (1, 1)})
    if modern:
        msp.add_lwpolyline([(0, 0), (5, 0), (5, 5)], dxfattribs=down)
    doc.blocks.new("FLIP").add_line((0, 0), (1, 0))
    msp.add_blockref("FLIP", (0, 0), dxfattribs=down)


def _units(code: int, size: float) -> Scenario:
    def draw(doc: Drawing, msp: Any, modern: bool) -> None:
        if modern:
            doc.header["$INSUNITS"] = code
        msp.add_line((0, 0), (size, 0))
        msp.add_circle((size / 2, size / 2), size / 10)

    return draw


def _far_from_origin(doc: Drawing, msp: Any, modern: bool) -> None:  # mine-grid northings
    msp.add_line((512_000.0, 7_250_000.0), (512_900.0, 7_250_400.0), dxfattribs={"layer": "WALLS"})
    msp.add_circle((512_300.0, 7_250_100.0), 4.0)


def _tiny(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_line((0, 0), (1e-6, 0))
    msp.add_circle((0, 0), 1e-7)


def _single_point(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_text("only", dxfattribs={"insert": (3, 3)})


def _undrawable(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_3dface([(0, 0, 0), (1, 0, 0), (1, 1, 0)])
    msp.add_solid([(0, 0), (1, 0), (1, 1)])
    msp.add_polyface().append_face([(0, 0, 0), (1, 0, 0), (1, 1, 1)])


def _empty(doc: Drawing, msp: Any, modern: bool) -> None:
    pass


def _huge_circle(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_circle((0, 0), 1e12)


def _spread(doc: Drawing, msp: Any, modern: bool) -> None:
    msp.add_line((0, 0), (1, 0))
    msp.add_line((0, 5e6), (1, 5e6))


SCENARIOS: dict[str, tuple[Scenario, bool]] = {  # name -> (how to draw it, whether it is importable)
    "lines": (_lines, True),
    "curves": (_curves, True),
    "hatches": (_hatches, True),
    "texts": (_texts, True),
    "blocks": (_blocks, True),
    "downward": (_downward, True),
    "millimetres": (_units(4, 50_000.0), True),
    "feet": (_units(2, 3000.0), True),
    "kilometres": (_units(7, 2.5), True),
    "far": (_far_from_origin, True),
    "tiny": (_tiny, True),
    "point": (_single_point, True),
    "undrawable": (_undrawable, False),
    "empty": (_empty, False),
    "huge-circle": (_huge_circle, False),
    "spread": (_spread, False),
}


def _everything(doc: Drawing, msp: Any, modern: bool) -> None:
    for name in ("lines", "curves", "hatches", "texts", "blocks", "downward"):
        SCENARIOS[name][0](doc, msp, modern)


def _ascii(doc: Drawing) -> str:
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue()


def _binary(doc: Drawing) -> bytes:
    with tempfile.TemporaryDirectory() as scratch:
        path = Path(scratch) / "plan.dxf"
        doc.saveas(path, fmt="bin")
        return path.read_bytes()


def _drawing(draw: Scenario, version: str) -> Drawing:
    doc = new_dxf(version)
    draw(doc, doc.modelspace(), version != "R12")
    return doc


def corpus() -> Iterator[CorpusFile]:
    """Every plan of the corpus (about 150 files, 2.5 MB, in a few seconds)."""
    for version in VERSIONS:
        for name, (draw, importable) in SCENARIOS.items():
            yield CorpusFile(f"{name}-{version}.dxf", _ascii(_drawing(draw, version)).encode(), importable)
        doc = _drawing(_everything, version)
        text = _ascii(doc)
        yield CorpusFile(f"everything-{version}-crlf.dxf", text.replace("\n", "\r\n").encode(), True)
        yield CorpusFile(f"everything-{version}-binary.dxf", _binary(doc), True)
        yield CorpusFile(f"everything-{version}-truncated.dxf", text[: len(text) // 2].encode(), False)
    yield from _damaged()


def _damaged() -> Iterator[CorpusFile]:
    doc = _drawing(_everything, "R2013")
    text = _ascii(doc)
    cp1252 = _drawing(_texts, "R12")
    cp1252.modelspace().add_text("Schacht Süd – Sohle 3", dxfattribs={"insert": (0, 0)})
    yield CorpusFile("cp1252-R12.dxf", _ascii(cp1252).encode("cp1252"), True)
    yield CorpusFile("bom-R2013.dxf", b"\xef\xbb\xbf" + text.encode(), True)
    yield CorpusFile("cr-R2013.dxf", text.replace("\n", "\r").encode(), True)
    yield CorpusFile("padded-values-R2013.dxf", text.replace("\n 10\n", "\n 10\n  ", 20).encode(), True)
    yield CorpusFile(
        "float-garbage-R2013.dxf", text.replace("\n 20\n0.0\n", "\n 20\n0.0m\n", 3).encode(), True
    )
    yield CorpusFile("bad-group-code-R2013.dxf", text.replace("\n  8\n", "\nxx\n", 1).encode(), False)
    minimal = "  0\nSECTION\n  2\nENTITIES\n  0\nLINE\n  8\nWALLS\n 10\n0\n 20\n0\n 11\n5\n 21\n5\n  0\nENDSEC\n  0\nEOF\n"
    yield CorpusFile("minimal-entities-only.dxf", minimal.encode(), True)
    missing = minimal.replace("LINE\n  8", "INSERT\n  2\nNOBLOCK\n  8")
    yield CorpusFile("missing-block.dxf", missing.encode(), False)
    yield CorpusFile("empty-file.dxf", b"", False)
    yield CorpusFile("garbage.dxf", bytes(range(256)) * 8, False)
    yield CorpusFile("pdf.dxf", b"%PDF-1.4\n" + b"x" * 200, False)
    yield CorpusFile("binary-garbage.dxf", b"AutoCAD Binary DXF\r\n\x1a\x00" + b"\xff" * 64, False)
    yield CorpusFile("utf16.dxf", text.encode("utf-16"), False)
