"""The dtype rule of the task state (sdbc_sim.task_state.DTYPE_RULE): attributes and
shapes of any real dtype are converted to float64 once per step on entry, and give
the features of their float64 values; other dtypes, and presence that is not bool,
are refused with the rule in the message."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.task_state import (
    DTYPE_RULE,
    GroupState,
    TaskState,
    TaskStateCheck,
    real_task_state,
    state_layout,
    validate_task_state,
)
from sdbc_states import PREDATOR_PREY, random_state

REAL_ARRAYS = ("attributes", "centres", "radii", "segments")


def cast(state: TaskState, dtype: type, labels=REAL_ARRAYS) -> TaskState:
    """The state with the arrays ``labels`` of every group cast to ``dtype``."""

    def group(g: GroupState) -> GroupState:
        changes = {
            label: getattr(g, label).astype(dtype)
            for label in labels
            if getattr(g, label) is not None
        }
        return dataclasses.replace(g, **changes)

    return dataclasses.replace(state, groups=tuple(group(g) for g in state.groups))


def run(states: list[TaskState]) -> np.ndarray:
    extractor = SdbcExtractor()
    extractor.start(PREDATOR_PREY, states[0].active.shape[0])
    for state in states:
        extractor.observe(state)
    return extractor.characterisations()


def float32_states() -> list[TaskState]:
    """Valid states whose values are float32 numbers (NaN where absent)."""
    rng = np.random.default_rng(5)
    states, previous = [], None
    for step in range(1, 6):
        previous = random_state(PREDATOR_PREY, 4, rng, step=step, previous=previous)
        states.append(cast(previous, np.float32))
    return states


def test_float32_gives_the_features_of_its_float64_values() -> None:
    states = float32_states()
    as_float64 = [cast(s, np.float64) for s in states]
    np.testing.assert_array_equal(run(states), run(as_float64))


def test_conversion_once_on_entry_and_none_for_float64() -> None:
    state = float32_states()[0]
    converted = real_task_state(PREDATOR_PREY, state)
    validate_task_state(PREDATOR_PREY, converted, 4)
    assert converted.groups[0].centres.dtype == np.float64
    # Already float64: the same object, nothing copied.
    assert real_task_state(PREDATOR_PREY, converted) is converted


def test_integer_and_bool_attributes_are_real() -> None:
    state = cast(float32_states()[0], np.float64)
    rounded = cast(
        dataclasses.replace(
            state,
            groups=tuple(
                dataclasses.replace(g, attributes=np.nan_to_num(g.attributes).round())
                for g in state.groups
            ),
        ),
        np.int32,
        ("attributes",),
    )
    converted = real_task_state(PREDATOR_PREY, rounded)
    assert converted.groups[0].attributes.dtype == np.float64
    np.testing.assert_array_equal(
        converted.groups[0].attributes, rounded.groups[0].attributes
    )


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (lambda g: dataclasses.replace(g, centres=g.centres + 0j), "dtype complex"),
        (lambda g: dataclasses.replace(g, centres=g.centres.astype(object)), "object"),
        (
            lambda g: dataclasses.replace(g, present=g.present.astype(np.int8)),
            "present has dtype int8",
        ),
    ],
)
def test_other_dtypes_are_refused_with_the_rule(change, pattern) -> None:
    state = float32_states()[0]
    bad = dataclasses.replace(
        state, groups=(change(state.groups[0]), *state.groups[1:])
    )
    with pytest.raises(ValueError, match=pattern) as refused:
        run([bad])
    assert DTYPE_RULE in str(refused.value)
    assert "group 'Predators'" in str(refused.value)


def test_validation_alone_states_the_rule() -> None:
    state = float32_states()[0]
    with pytest.raises(ValueError, match="dtype float32, expected float64") as refused:
        validate_task_state(PREDATOR_PREY, state, 4)
    assert "real_task_state converts" in str(refused.value)


def test_a_checked_stream_converts_and_refuses_as_each_state_would() -> None:
    """TaskStateCheck passes a state laid out as the last one accepted without
    reading it again, and gives any other what real_task_state and
    validate_task_state give it alone."""
    check = TaskStateCheck(PREDATOR_PREY, 4)
    rng = np.random.default_rng(3)
    exact = [random_state(PREDATOR_PREY, 4, rng, step=s) for s in range(1, 4)]
    assert all(check(state) is state for state in exact)
    assert check.layout is not None and check.layout == state_layout(exact[-1])
    single = float32_states()[0]
    converted = check(single)
    assert converted is not single
    assert converted.groups[0].centres.dtype == np.float64
    assert check(exact[0]) is exact[0]
    bad = dataclasses.replace(
        exact[0],
        groups=(
            dataclasses.replace(
                exact[0].groups[0], centres=exact[0].groups[0].centres + 0j
            ),
            *exact[0].groups[1:],
        ),
    )
    with pytest.raises(ValueError) as alone:
        real_task_state(PREDATOR_PREY, bad)
    with pytest.raises(ValueError) as streamed:
        check(bad)
    assert str(streamed.value) == str(alone.value)
    wide = dataclasses.replace(exact[0], active=np.ones(5, dtype=bool))
    with pytest.raises(ValueError, match=r"active must be a \(4,\) bool array"):
        check(wide)
    assert check(exact[1]) is exact[1]
