"""The smaller boundaries of issue 38: the state count's size and the state
deviation of static groups (the lock note on a full disk is tested with the
study's full disk, tests/sdbc_evolution/study/test_boundaries_study.py)."""

from __future__ import annotations

import pytest
from sdbc_evolution.characterise.sdbc import SdbcOptions, sdbc_dimension_names
from sdbc_evolution.characterise.sensor_effector import StateCountOptions
from sdbc_sim.limits import STATE_COUNT_STATES
from sdbc_sim.settings import SettingsError
from sdbc_sim.task_state import EntityGroupSpec, Geometry, TaskDescription


def test_a_state_count_beyond_its_limit_is_refused_naming_it() -> None:
    StateCountOptions(levels=3, max_states=STATE_COUNT_STATES)
    with pytest.raises(SettingsError, match="max_states: Input should be less"):
        StateCountOptions(levels=3, max_states=43_046_721)


def test_state_deviation_covers_static_groups() -> None:
    # Static: the chargers do not move, but their load changes.
    description = TaskDescription(
        name="chargers",
        groups=(
            EntityGroupSpec(
                name="Robot", attributes=("x",), min_size=2, max_size=2,
                static=False, geometry=Geometry.POINT,
            ),
            EntityGroupSpec(
                name="Charger", attributes=("load",), min_size=3, max_size=3,
                static=True, geometry=Geometry.CIRCLE,
            ),
        ),
    )  # fmt: skip
    names = sdbc_dimension_names(description, SdbcOptions(state_deviation=True))
    assert any("Charger load deviation" in n for n in names), names
    assert any("Robot x deviation" in n for n in names), names
