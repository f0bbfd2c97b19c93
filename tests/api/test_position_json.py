"""The position list's JSON, encoded straight from the service's views, is what ``list[PositionRead]`` gives."""

from __future__ import annotations

import json
from datetime import UTC, datetime

from pydantic import TypeAdapter

from driftmap.api.schemas_access import PositionRead, position_list_json
from driftmap.services.positions import PositionView


def _views() -> list[PositionView]:
    received = datetime(2026, 12, 5, 17, 3, 4, 250_000, tzinfo=UTC)
    bare = PositionView(1, 2, "loc-01", 3, 12.5, 40, 101.25, -7.5, None, 0.0, False, True, None, received)
    full = PositionView(
        2, 2, "loc-01", 3, 12.6, 41, 101.5, -7.25, -3.1, 0.97, True, False, 4, received, speed_mps=-1.5,
        moving=True, odometry=True, obscured=True, obscured_reason="dust", salient=0.2, sharpness=310.0,
        speckle=0.04, flat_area=0.0,
    )  # fmt: skip
    quiet = PositionView(3, 5, "näme \"quoted\"", 3, 1e9, 0, 0.0, 0.0, 0.0, 1.0, True, False, 1, received,
                         speed_mps=0.0, moving=False, obscured=False)  # fmt: skip
    return [bare, full, quiet]


def test_the_encoded_list_is_the_validated_models_json() -> None:
    views = _views()
    validated = TypeAdapter(list[PositionRead]).dump_python(
        [PositionRead.model_validate(view) for view in views], mode="json"
    )
    assert json.loads(position_list_json(views)) == validated
    assert json.loads(position_list_json([])) == []


def test_every_field_of_the_schema_is_in_the_view() -> None:
    encoded = json.loads(position_list_json(_views()[:1]))[0]
    assert set(encoded) == set(PositionRead.model_fields)
    assert encoded["received_at"] == "2026-12-05T17:03:04.250000Z"
