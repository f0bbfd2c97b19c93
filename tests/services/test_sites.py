"""Tests of driftmap.services.sites that need no database: the survey limits taken from the settings."""

from __future__ import annotations

import pytest

from driftmap.config import Settings
from driftmap.formats.survey_dxf import DEFAULT_LIMITS
from driftmap.services import sites as site_service


class TestSurveyLimits:
    def test_the_default_settings_are_the_readers_defaults(self) -> None:
        assert site_service.survey_limits(Settings()) == DEFAULT_LIMITS

    def test_each_limit_is_set_by_its_variable(self, monkeypatch: pytest.MonkeyPatch) -> None:
        monkeypatch.setenv("DRIFTMAP_SURVEY_MAX_EXTENT_M", "5000")
        monkeypatch.setenv("DRIFTMAP_SURVEY_MAX_STORED_BYTES", "1000")
        limits = site_service.survey_limits(Settings())
        assert (limits.max_extent_m, limits.max_stored_bytes) == (5000.0, 1000)
        assert limits.max_points == DEFAULT_LIMITS.max_points
