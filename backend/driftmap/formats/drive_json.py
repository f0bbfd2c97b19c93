"""``drive.json`` and the ``camera`` block it shares with video calibration files (``docs/formats.md``).

Parsing is strict about what the format names (types, ranges, the format string) and ignores keys it
does not know. JSON errors and bad values name the file, the 1-based line and the key.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any, cast

from driftmap.core.imaging.lens import LENS_MODELS, Lens
from driftmap.core.odometry.camera import CameraModel
from driftmap.errors import BadInputError
from driftmap.formats.bounds import MAX_CAMERA_SIDE_PX
from driftmap.formats.records import (
    DRIVE_FORMAT,
    DRIVE_FORMAT_LENS,
    DRIVE_FORMATS,
    DRIVE_KINDS,
    DriveKind,
    DriveMeta,
)

_KEY_RE = re.compile(r'"([^"\\]*)"\s*:')
CAMERA_KEYS: tuple[str, ...] = ("width", "height", "ground_roi", "k_x", "k_y", "y_c", "y_h", "forward_sign")


def camera_to_json(camera: CameraModel) -> dict[str, Any]:
    """The ``camera`` block for ``camera``: keys exactly as formats.md, floats exact."""
    block: dict[str, Any] = {
        "width": int(camera.width_px),
        "height": int(camera.height_px),
        "ground_roi": [int(v) for v in camera.ground_roi_px],
        "k_x": float(camera.k_x_m_per_px),
        "k_y": float(camera.k_y_m_per_px),
        "y_c": float(camera.y_c_m),
        "y_h": float(camera.y_h_m),
        "forward_sign": int(camera.forward_sign),
    }
    if camera.ground_homography is not None:
        block["ground_homography"] = [[float(v) for v in row] for row in camera.ground_homography]
    if camera.lens is not None:
        block["lens"] = lens_to_json(camera.lens)
    return block


def lens_to_json(lens: Lens) -> dict[str, Any]:
    """The ``lens`` object of a camera block: ``model``, ``K`` (3x3, pixels), ``distortion``."""
    return {
        "model": lens.model,
        "K": [[float(v) for v in row] for row in lens.K],
        "distortion": [float(v) for v in lens.distortion],
    }


def parse_lens_block(lens: object, text: str, file: str | Path) -> Lens:
    """Validate a camera block's ``lens`` object (already parsed from ``text``).

    Raises:
        BadInputError: not an object, an unknown model, a K that is not 3x3 of finite numbers with
            positive focal lengths, or the wrong number of distortion coefficients; names ``camera.lens.*``.
    """

    def bad(key: str, message: str) -> BadInputError:
        return BadInputError(message, file=file, line=_line_of(text, "lens", key), field=f"camera.lens.{key}")

    if not isinstance(lens, dict):
        raise BadInputError(
            "lens must be a JSON object", file=file, line=_line_of(text, "lens"), field="camera.lens"
        )
    for key in ("model", "K", "distortion"):
        if key not in lens:
            raise BadInputError(
                "missing key", file=file, line=_line_of(text, "lens"), field=f"camera.lens.{key}"
            )
    model, k, dist = lens["model"], lens["K"], lens["distortion"]
    if model not in LENS_MODELS:
        raise bad("model", f"must be one of {', '.join(LENS_MODELS)}, found {json.dumps(model)[:60]}")
    if not (
        isinstance(k, list) and len(k) == 3 and all(isinstance(r, list) and len(r) == 3 for r in k)
        and all(_finite(v) for r in k for v in r)
    ):  # fmt: skip
        raise bad("K", "must be a 3x3 list of finite numbers")
    if not isinstance(dist, list) or not all(_finite(v) for v in dist):
        raise bad("distortion", "must be a list of finite numbers")
    try:
        return Lens(model, tuple((float(r[0]), float(r[1]), float(r[2])) for r in k), tuple(map(float, dist)))
    except BadInputError as exc:
        key = (exc.field or "lens.K").removeprefix("lens.")
        raise bad(key, exc.reason) from None


def _finite(v: object) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)


def meta_to_json(meta: DriveMeta) -> dict[str, Any]:
    """The whole ``drive.json`` object for ``meta``."""
    return {
        "format": DRIVE_FORMAT if meta.camera.lens is None else DRIVE_FORMAT_LENS,
        "name": meta.name,
        "kind": meta.kind,
        "fps": float(meta.fps),
        "camera": camera_to_json(meta.camera),
    }


def dump_drive_json(meta: DriveMeta) -> str:
    """``drive.json`` text: plain JSON, two-space indent, a final newline.

    Raises:
        ValueError: a non-finite number in ``meta``.
    """
    return _dump(meta_to_json(meta), "") + "\n"


def json_text(value: Any) -> str:
    """JSON text as the writers emit it: one key per line, two-space indent, lists on one line, final newline."""
    return _dump(value, "") + "\n"


def _dump(value: Any, indent: str) -> str:
    """JSON with one key per line and lists kept on one line."""
    if not isinstance(value, dict):
        return json.dumps(value, allow_nan=False, ensure_ascii=False)
    inner = indent + "  "
    items = [f"{inner}{json.dumps(k, ensure_ascii=False)}: {_dump(v, inner)}" for k, v in value.items()]
    return "{\n" + ",\n".join(items) + "\n" + indent + "}"


def checked_drive_json(meta: DriveMeta, file: str | Path) -> str:
    """:func:`dump_drive_json`, refusing anything :func:`parse_drive_json` would refuse.

    Raises:
        BadInputError: a non-finite number or a value out of range, naming ``file`` and the key.
    """
    bad_key = _non_finite_key(meta_to_json(meta))
    if bad_key is not None:
        raise BadInputError("must be a finite number", file=file, field=bad_key)
    text = dump_drive_json(meta)
    parse_drive_json(text, file)
    return text


def _non_finite_key(value: object, key: str = "") -> str | None:
    """The dotted key of the first NaN or infinity inside a JSON-like value, or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return key
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else []
    for child_key, child in items:
        found = _non_finite_key(
            child, f"{key}.{child_key}" if key and isinstance(child_key, str) else key or str(child_key)
        )
        if found is not None:
            return found
    return None


def load_json(text: str, file: str | Path) -> Any:
    """Parse JSON text; syntax errors, NaN/Infinity and duplicate keys name the file and line."""

    def reject_constant(name: str) -> Any:
        pos = text.find(name)
        keys = list(_KEY_RE.finditer(text, 0, max(pos, 0)))
        raise BadInputError(
            f"{name} is not allowed in JSON",
            file=file,
            line=text.count("\n", 0, pos) + 1 if pos >= 0 else None,
            field=keys[-1].group(1) if keys else None,
        )

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in items:
            if key in out:
                raise BadInputError(
                    "duplicate key", file=file, line=_line_of(text, key, last=True), field=key
                )
            out[key] = value
        return out

    try:
        return json.loads(text, parse_constant=reject_constant, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        keys = list(_KEY_RE.finditer(text, 0, exc.pos))
        raise BadInputError(
            f"invalid JSON: {exc.msg} (column {exc.colno})",
            file=file,
            line=exc.lineno,
            field=keys[-1].group(1) if keys else None,
        ) from None
    except RecursionError:
        raise BadInputError("JSON nested too deeply", file=file, line=1) from None


def parse_drive_json(text: str, file: str | Path) -> DriveMeta:
    """Parse and validate ``drive.json`` text.

    Raises:
        BadInputError: bad JSON, a wrong ``format``, a missing or ill-typed key, a bad ``kind``, ``fps``
            not finite and positive, or a camera block that does not fit together.
    """
    obj = load_json(text, file)
    if not isinstance(obj, dict):
        raise BadInputError("drive.json must hold a JSON object", file=file, line=1)
    fmt = _require(obj, "format", text, file)
    if fmt not in DRIVE_FORMATS:
        raise BadInputError(
            f"format must be one of {', '.join(DRIVE_FORMATS)}, found {json.dumps(fmt)[:60]}",
            file=file,
            line=_line_of(text, "format"),
            field="format",
        )
    name = _require(obj, "name", text, file)
    if not isinstance(name, str) or not name.strip():
        raise BadInputError(
            "name must be a non-empty string", file=file, line=_line_of(text, "name"), field="name"
        )
    kind = _require(obj, "kind", text, file)
    if kind not in DRIVE_KINDS:
        raise BadInputError(
            f"kind must be one of {', '.join(DRIVE_KINDS)}, found {json.dumps(kind)[:60]}",
            file=file,
            line=_line_of(text, "kind"),
            field="kind",
        )
    fps = _number(_require(obj, "fps", text, file), "fps", text, file)
    if fps <= 0:
        raise BadInputError("fps must be positive", file=file, line=_line_of(text, "fps"), field="fps")
    camera = parse_camera_block(_require(obj, "camera", text, file), text, file)
    if (camera.lens is None) != (fmt == DRIVE_FORMAT):  # the format says whether the camera has a lens
        message = (
            f"a camera with a lens needs format '{DRIVE_FORMAT_LENS}'"
            if camera.lens is not None
            else f"format '{DRIVE_FORMAT_LENS}' is for a camera with a lens; without one it is '{DRIVE_FORMAT}'"
        )
        raise BadInputError(message, file=file, line=_line_of(text, "format"), field="format")
    return DriveMeta(name=name, kind=cast(DriveKind, kind), fps=fps, camera=camera)


def parse_camera_block(block: object, text: str, file: str | Path) -> CameraModel:
    """Validate a ``camera`` block (already parsed from ``text``) into a :class:`CameraModel`.

    Args:
        block: the parsed JSON value of the ``camera`` key.
        text: the whole JSON text, used only to find line numbers for errors.
        file: the file name used in error messages.

    Raises:
        BadInputError: a missing or ill-typed key, a width or height outside 1 to ``MAX_CAMERA_SIDE_PX``
            pixels, or a ``ground_roi`` outside the frame.
    """
    if not isinstance(block, dict):
        raise BadInputError(
            "camera must be a JSON object", file=file, line=_line_of(text, "camera"), field="camera"
        )

    def value(key: str) -> Any:
        if key not in block:
            raise BadInputError(
                "missing key", file=file, line=_line_of(text, "camera"), field=f"camera.{key}"
            )
        return block[key]

    def bad(key: str, message: str) -> BadInputError:
        return BadInputError(message, file=file, line=_line_of(text, "camera", key), field=f"camera.{key}")

    def integer(key: str) -> int:
        v = value(key)
        if isinstance(v, bool) or not isinstance(v, int):
            raise bad(key, f"must be an integer, found {json.dumps(v)[:60]}")
        return v

    def number(key: str, *, positive: bool = False) -> float:
        v = value(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise bad(key, f"must be a finite number, found {json.dumps(v)[:60]}")
        if positive and v <= 0:
            raise bad(key, f"must be positive, found {v}")
        return float(v)

    width, height = integer("width"), integer("height")
    for key, size in (("width", width), ("height", height)):
        if not 1 <= size <= MAX_CAMERA_SIDE_PX:
            raise bad(key, f"must be 1 to {MAX_CAMERA_SIDE_PX} pixels, found {size}")
    roi = value("ground_roi")
    if (
        not isinstance(roi, list)
        or len(roi) != 4
        or any(isinstance(v, bool) or not isinstance(v, int) for v in roi)
    ):
        raise bad("ground_roi", f"must be a list of 4 integers [x, y, w, h], found {json.dumps(roi)[:60]}")
    x, y, w, h = roi
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise bad("ground_roi", f"[{x}, {y}, {w}, {h}] does not lie inside the {width}x{height} frame")
    k_x, k_y = number("k_x", positive=True), number("k_y", positive=True)
    y_c, y_h = number("y_c"), number("y_h")
    sign = value("forward_sign")
    if isinstance(sign, bool) or sign not in (1, -1):
        raise bad("forward_sign", f"must be 1 or -1, found {json.dumps(sign)[:60]}")
    homography: tuple[tuple[float, float, float], ...] | None = None
    if block.get("ground_homography") is not None:
        hom = block["ground_homography"]
        if not (
            isinstance(hom, list)
            and len(hom) == 3
            and all(isinstance(r, list) and len(r) == 3 for r in hom)
            and all(
                not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
                for r in hom
                for v in r
            )
        ):
            raise bad("ground_homography", "must be a 3x3 list of finite numbers")
        homography = tuple((float(r[0]), float(r[1]), float(r[2])) for r in hom)
    lens = parse_lens_block(block["lens"], text, file) if "lens" in block else None
    return CameraModel(
        width_px=width,
        height_px=height,
        ground_roi_px=(x, y, w, h),
        k_x_m_per_px=k_x,
        k_y_m_per_px=k_y,
        y_c_m=y_c,
        y_h_m=y_h,
        forward_sign=int(sign),
        ground_homography=homography,
        lens=lens,
    )


def _require(obj: dict[str, Any], key: str, text: str, file: str | Path) -> Any:
    if key not in obj:
        raise BadInputError("missing key", file=file, line=1, field=key)
    return obj[key]


def _number(v: object, key: str, text: str, file: str | Path) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise BadInputError(
            f"must be a finite number, found {json.dumps(v)[:60]}",
            file=file,
            line=_line_of(text, key),
            field=key,
        )
    return float(v)


def _line_of(text: str, *path: str, last: bool = False) -> int | None:
    """1-based line of the key at the end of ``path``, each key searched after the previous one.

    A parent key that is absent is skipped (a calibration file may hold the camera block unwrapped).
    """
    pos = 0
    for depth, key in enumerate(path, start=1):
        pattern = re.compile(r'"' + re.escape(key) + r'"\s*:')
        matches = list(pattern.finditer(text, pos)) if last else [m for m in [pattern.search(text, pos)] if m]
        if matches:
            pos = matches[-1].start()
        elif depth == len(path):
            return None
    return text.count("\n", 0, pos) + 1
