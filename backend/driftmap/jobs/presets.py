"""The mapping parameters a build job asks for by name (its ``preset`` argument)."""

from __future__ import annotations

from typing import Any

from driftmap.core.mapping.pipeline import MAP_PRESETS, MappingParams
from driftmap.errors import BadInputError


def preset_params(args: dict[str, Any]) -> tuple[str, MappingParams]:
    """(name, parameters) of the job args' ``preset`` (default ``paper``).

    Raises:
        BadInputError: no such preset.
    """
    preset = str(args.get("preset", "paper"))
    if preset not in MAP_PRESETS:
        raise BadInputError(f"unknown preset {preset!r}; one of {', '.join(MAP_PRESETS)}", field="preset")
    return preset, MAP_PRESETS[preset]
