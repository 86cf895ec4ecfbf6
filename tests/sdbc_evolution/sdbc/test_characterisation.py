"""The SDBC extractor as an engine observer: raw vectors, names, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)
from sdbc_states import SMALL, SMALL_NAMES, small_state

NAN = math.nan


def test_dimension_names() -> None:
    assert dimension_names(SMALL) == (
        *(f"{n} (M)" for n in SMALL_NAMES),
        *(f"{n} (F)" for n in SMALL_NAMES),
        "Simulation length",
    )


def test_hand_computed_characterisation() -> None:
    # Two trials. Trial 0 has robots 0 and 2, then robot 2 alone, then none, and
    # ends after 3 steps; trial 1 has robot 2 alone, then ends after 1 step.
    steps = [
        [[True, False, True], [False, False, True]],
        [[False, False, True], [True, True, True]],
        [[False, False, False], [True, True, True]],
    ]
    active = [[True, True], [True, False], [True, False]]
    extractor = SdbcExtractor()
    extractor.start(SMALL, 2)
    assert extractor.dimension_names == dimension_names(SMALL)
    for k, (present, act) in enumerate(zip(steps, active, strict=True), start=1):
        state = small_state(present)
        state.step = k
        state.active = np.array(act)
        extractor.observe(state)
    vectors = extractor.characterisations()
    assert vectors.shape == (2, 13)

    b0 = 10.0 - 1.0  # robot 0 to the beacon
    b2 = math.sqrt(40.0) - 1.0  # robot 2 to the beacon
    # Per-step values of trial 0 (size, speed, dispersion, beacon, fence, is on):
    #   step 1: 2/3, 3, 8, (b0+b2)/2, 6, 1;  step 2: 1/3, 4, -, b2, 10, 1;
    #   step 3: 0, -, -, -, -, 1.
    means_0 = [1 / 3, 3.5, 8.0, ((b0 + b2) / 2 + b2) / 2, 8.0, 1.0]
    finals_0 = [0.0, 4.0, 8.0, b2, 10.0, 1.0]
    np.testing.assert_allclose(vectors[0], [*means_0, *finals_0, 3.0], atol=1e-12)
    # Trial 1: one step with robot 2 alone; its dispersion is never defined: 0.
    values_1 = [1 / 3, 4.0, 0.0, b2, 10.0, 1.0]
    np.testing.assert_allclose(vectors[1], [*values_1, *values_1, 1.0], atol=1e-12)
    np.testing.assert_array_equal(extractor.lengths, [3, 1])


def test_reuse_for_a_new_batch() -> None:
    extractor = SdbcExtractor()
    extractor.start(SMALL, 1)
    extractor.observe(small_state([[True, True, True]]))
    extractor.start(SMALL, 2)
    extractor.observe(small_state([[True, False, False], [True, False, False]]))
    vectors = extractor.characterisations()
    assert vectors.shape == (2, 13)
    np.testing.assert_array_equal(vectors[:, -1], [1.0, 1.0])


def observed(extractor: SdbcExtractor, present, step: int = 1, active=None):
    state = small_state(present)
    state.step = step
    if active is not None:
        state.active = np.array(active)
    extractor.observe(state)
    return state


def test_steps_must_arrive_in_order() -> None:
    extractor = SdbcExtractor()
    extractor.start(SMALL, 1)
    with pytest.raises(ValueError, match="step 2 follows step 0"):
        observed(extractor, [[True, True, True]], step=2)


def test_an_ended_trial_cannot_resume() -> None:
    extractor = SdbcExtractor()
    extractor.start(SMALL, 2)
    observed(extractor, [[True] * 3] * 2, step=1, active=[True, False])
    with pytest.raises(ValueError, match="trial 1 is active again"):
        observed(extractor, [[True] * 3] * 2, step=2, active=[True, True])


def test_nan_in_a_present_entity_is_named() -> None:
    extractor = SdbcExtractor()
    extractor.start(SMALL, 2)
    state = small_state([[True, True, True], [True, False, True]])
    state.groups[0].attributes[1, 2, 0] = NAN
    with pytest.raises(
        ValueError, match=r"trial 1: feature 'Robots speed' is not finite"
    ):
        extractor.observe(state)
    extractor.start(SMALL, 2)
    state = small_state([[True, True, True], [True, False, True]])
    state.groups[0].centres[0, 1, 0] = math.inf
    with pytest.raises(ValueError, match=r"trial 0: feature 'Robots dispersion'"):
        extractor.observe(state)


def test_nan_is_named_when_only_active_trials_are_computed() -> None:
    extractor = SdbcExtractor(compact_below=1.0)
    extractor.start(SMALL, 3)
    state = small_state([[True, True, True]] * 3)
    state.active = np.array([False, True, True])
    state.groups[0].attributes[2, 1, 0] = NAN
    with pytest.raises(ValueError, match=r"trial 2: feature 'Robots speed'"):
        extractor.observe(state)


def test_bad_settings_are_named() -> None:
    with pytest.raises(ValueError, match="compact_below 1.5"):
        SdbcExtractor(compact_below=1.5)


def test_nan_in_an_ended_trial_is_ignored() -> None:
    extractor = SdbcExtractor()
    extractor.start(SMALL, 2)
    state = small_state([[True, True, True], [True, False, True]])
    state.groups[0].attributes[1, 2, 0] = NAN
    state.active = np.array([True, False])
    extractor.observe(state)
    assert np.isfinite(extractor.characterisations()).all()


def test_a_full_group_missing_an_entity_is_named() -> None:
    extractor = SdbcExtractor()
    extractor.start(SMALL, 1)
    state = small_state([[True, True, True]])
    state.groups[1].present = np.zeros((1, 1), dtype=bool)
    with pytest.raises(ValueError, match=r"group 'Beacon' \(min_size = max_size = 1\)"):
        extractor.observe(state)


def test_a_group_below_its_minimum_size_is_named() -> None:
    description = TaskDescription(
        "pair",
        (
            EntityGroupSpec(
                name="Dots",
                attributes=(),
                min_size=2,
                max_size=3,
                static=False,
                geometry=Geometry.POINT,
            ),
        ),
    )
    present = np.array([[True, True, False], [False, True, False]])
    state = TaskState(
        1,
        np.ones(2, bool),
        (GroupState(present, np.empty((2, 3, 0)), centres=np.zeros((2, 3, 2))),),
    )
    extractor = SdbcExtractor()
    extractor.start(description, 2)
    with pytest.raises(ValueError, match=r"trial 1: group 'Dots' holds 1 entities"):
        extractor.observe(state)


def test_use_before_start_is_an_error() -> None:
    with pytest.raises(RuntimeError, match="start"):
        SdbcExtractor().characterisations()
    with pytest.raises(ValueError, match="n_trials 0"):
        SdbcExtractor().start(SMALL, 0)


def _one_row_per_trial(group: GroupState, n_trials: int) -> GroupState:
    """``group`` with every shared row (a leading dimension of 1) repeated."""

    def repeat(array: np.ndarray | None) -> np.ndarray | None:
        if array is None or array.shape[0] != 1:
            return array
        return np.repeat(array, n_trials, axis=0)

    return GroupState(
        present=repeat(group.present),
        attributes=repeat(group.attributes),
        centres=repeat(group.centres),
        radii=repeat(group.radii),
        segments=repeat(group.segments),
    )


def test_shared_rows_give_the_same_features_as_repeated_rows() -> None:
    presence = [[True, False, True], [False, True, True], [True, True, True]]
    vectors = []
    for share in (True, False):
        extractor = SdbcExtractor()
        extractor.start(SMALL, 3)
        for k in (1, 2, 3):
            state = small_state(presence)
            state.step = k
            if not share:
                state.groups = tuple(_one_row_per_trial(g, 3) for g in state.groups)
            extractor.observe(state)
        vectors.append(extractor.characterisations())
    shared_state = small_state(presence)
    assert shared_state.groups[1].present.shape[0] == 1  # the test shares rows
    assert shared_state.groups[2].segments.shape[0] == 1
    np.testing.assert_array_equal(vectors[0], vectors[1])


def test_a_leading_dimension_other_than_trials_or_one_is_refused_by_group() -> None:
    state = small_state([[True, False, True], [True, True, True]])
    beacon = state.groups[1]
    beacon.attributes = np.ones((3, 1, 1))
    extractor = SdbcExtractor()
    extractor.start(SMALL, 2)
    with pytest.raises(
        ValueError,
        match=r"group 'Beacon': attributes has 3 rows, expected 2 \(one per trial\) "
        r"or 1 \(shared by every trial\)",
    ):
        extractor.observe(state)


def test_entity_groups_are_declared_by_keyword_and_checked() -> None:
    spec = EntityGroupSpec(
        name="Beacon",
        attributes=["is on"],
        min_size=1,
        max_size=1,
        static=True,
        geometry="point",
    )
    assert spec.attributes == ("is on",) and spec.geometry is Geometry.POINT
    assert spec.static and spec.is_static
    with pytest.raises(TypeError):
        EntityGroupSpec("Beacon", ("is on",), 1, 1, True, Geometry.POINT)  # type: ignore[misc]
    good = dict(
        name="Beacon",
        attributes=("is on",),
        min_size=1,
        max_size=1,
        static=True,
        geometry=Geometry.POINT,
    )
    for change, message in (
        ({"max_size": 1.5}, "max_size must be an integer"),
        ({"min_size": True}, "min_size must be an integer"),
        ({"static": "yes"}, "static must be True or False"),
        ({"geometry": "cube"}, "geometry must be one of"),
        ({"attributes": "is on"}, "attributes must be a sequence of names"),
        ({"name": ""}, "the name must be a non-empty string"),
    ):
        with pytest.raises(ValueError, match=message):
            EntityGroupSpec(**{**good, **change})


def _nan_speed(state: TaskState) -> None:
    state.groups[0].attributes[1, 2, 0] = NAN


def _no_beacon(state: TaskState) -> None:
    state.groups[1].present = np.zeros((1, 1), dtype=bool)


def _complex_speeds(state: TaskState) -> None:
    state.groups[0].attributes = state.groups[0].attributes + 0j


def _three_rows(state: TaskState) -> None:
    state.groups[1].attributes = np.ones((3, 1, 1))


def _presence_as_numbers(state: TaskState) -> None:
    state.groups[0].present = state.groups[0].present.astype(np.int8)


def _no_centres(state: TaskState) -> None:
    state.groups[0].centres = None


def _active_of_three(state: TaskState) -> None:
    state.active = np.ones(3, dtype=bool)


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (_nan_speed, r"trial 1: feature 'Robots speed' is not finite"),
        (_no_beacon, r"group 'Beacon' \(min_size = max_size = 1\) misses an entity"),
        (_complex_speeds, r"group 'Robots': attributes has dtype complex128"),
        (_three_rows, r"group 'Beacon': attributes has 3 rows, expected 2"),
        (_presence_as_numbers, r"group 'Robots': present has dtype int8"),
        (_no_centres, r"group 'Robots': centres is missing"),
        (_active_of_three, r"active must be a \(2,\) bool array"),
    ],
)
@pytest.mark.parametrize("good_steps", [0, 3])
def test_bad_input_after_good_steps_is_named_alike(
    change, pattern: str, good_steps: int
) -> None:
    """After steps of one layout, whose states are checked and computed as the
    first one decided, a bad state gets the message it gets as the first."""
    present = [[True, True, True], [True, False, True]]
    extractor = SdbcExtractor()
    extractor.start(SMALL, 2)
    for step in range(1, good_steps + 1):
        state = small_state(present)
        state.step = step
        extractor.observe(state)
    state = small_state(present)
    state.step = good_steps + 1
    change(state)
    with pytest.raises(ValueError, match=pattern):
        extractor.observe(state)
