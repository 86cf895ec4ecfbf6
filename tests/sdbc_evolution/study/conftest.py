"""Fixtures of the study tests."""

from __future__ import annotations

import pytest
from sdbc_evolution.study.presets import StudyPreset
from study_helpers import tiny_preset as make_tiny_preset


@pytest.fixture
def tiny_preset() -> StudyPreset:
    return make_tiny_preset()
