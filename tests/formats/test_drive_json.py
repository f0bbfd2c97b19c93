"""Tests of driftmap.formats.drive_json: the camera block and drive.json, exact and strict."""

from __future__ import annotations

import json
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from driftmap.errors import BadInputError
from driftmap.formats.drive_json import (
    CAMERA_KEYS,
    camera_to_json,
    dump_drive_json,
    meta_to_json,
    parse_camera_block,
    parse_drive_json,
)
from driftmap.formats.records import DriveMeta
from tests.formats.builders import make_camera, make_meta

JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


class TestCameraBlock:
    def test_keys_exactly_as_the_format(self) -> None:
        assert tuple(camera_to_json(make_camera())) == CAMERA_KEYS
        assert tuple(camera_to_json(make_camera(homography=True))) == (*CAMERA_KEYS, "ground_homography")

    @pytest.mark.parametrize("homography", [False, True])
    def test_round_trip(self, homography: bool) -> None:
        camera = make_camera(homography=homography)
        assert parse_camera_block(camera_to_json(camera), "", "calib.json") == camera

    def test_unknown_keys_are_ignored(self) -> None:
        block = {**camera_to_json(make_camera()), "mount": "rear"}
        assert parse_camera_block(block, "", "c.json") == make_camera()

    @pytest.mark.parametrize(
        ("key", "value"),
        [
            ("width", 0),
            ("width", 32.0),
            ("width", 100_000),
            ("height", 2**70),
            ("height", True),
            ("k_y", -0.1),
            ("y_h", float("inf")),
            ("ground_roi", [-1, 0, 4, 4]),
            ("ground_roi", [0, 0, 0, 4]),
            ("ground_roi", [0.5, 0, 4, 4]),
            ("ground_homography", [[1, 0, 0], [0, 1, 0]]),
            ("ground_homography", [[1, 0, 0], [0, 1, 0], [0, 0, "1"]]),
        ],
    )
    def test_bad_values_name_the_key(self, key: str, value: Any) -> None:
        block = {**camera_to_json(make_camera()), key: value}
        with pytest.raises(BadInputError) as info:
            parse_camera_block(block, "", "calib.json")
        assert (info.value.file, info.value.field) == ("calib.json", f"camera.{key}")

    def test_not_an_object(self) -> None:
        with pytest.raises(BadInputError, match="object"):
            parse_camera_block([1, 2], "", "c.json")


class TestDriveJson:
    def test_dump_then_parse(self) -> None:
        meta = make_meta(homography=True, kind="localisation")
        assert parse_drive_json(dump_drive_json(meta), "drive.json") == meta

    def test_plain_json_with_the_format_string(self) -> None:
        obj = json.loads(dump_drive_json(make_meta()))
        assert obj["format"] == "driftmap-drive/1"
        assert obj == meta_to_json(make_meta())

    def test_dump_refuses_nan(self) -> None:
        meta = DriveMeta(name="n", kind="mapping", fps=float("nan"), camera=make_camera())
        with pytest.raises(ValueError, match="JSON"):
            dump_drive_json(meta)

    @pytest.mark.parametrize("text", ["", "[]", "{", '{"format": "driftmap-drive/1"}', "\n\n  tru"])
    def test_short_or_wrong_documents(self, text: str) -> None:
        with pytest.raises(BadInputError) as info:
            parse_drive_json(text, "drive.json")
        assert info.value.file == "drive.json" and info.value.line is not None

    @settings(max_examples=150, deadline=None)
    @given(st.sampled_from(["format", "name", "kind", "fps", "camera", *CAMERA_KEYS]), JSON_VALUES)
    def test_any_value_anywhere_gives_meta_or_bad_input(self, key: str, value: Any) -> None:
        obj = meta_to_json(make_meta())
        (obj if key in ("format", "name", "kind", "fps", "camera") else obj["camera"])[key] = value
        try:
            text = json.dumps(obj, indent=2)
        except ValueError:
            return
        try:
            parse_drive_json(text, "drive.json")
        except BadInputError as exc:
            assert exc.file == "drive.json" and exc.field is not None

    @settings(max_examples=150, deadline=None)
    @given(st.text(max_size=120))
    def test_garbage_text_gives_bad_input(self, text: str) -> None:
        with pytest.raises(BadInputError):
            parse_drive_json(text, "drive.json")
