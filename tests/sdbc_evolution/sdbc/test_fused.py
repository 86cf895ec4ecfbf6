"""The compiled feature loops (sdbc/fused.py) against the numpy formulation, to the
bit: ``StepFeatures(fused=False)`` is the oracle."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
from sdbc_evolution.sdbc.features import StepFeatures, behaviour_features
from sdbc_evolution.sdbc.options import SdbcOptions
from sdbc_sim.task_state import GroupState, TaskDescription, TaskState
from sdbc_sim.tasks import available_tasks, make_task
from sdbc_states import (
    GATE_ESCAPE,
    PREDATOR_PREY,
    RESOURCE_SHARING,
    SMALL,
    random_state,
    small_state,
)

DESCRIPTIONS = [GATE_ESCAPE, RESOURCE_SHARING, PREDATOR_PREY, SMALL] + [
    make_task(name).description for name in sorted(available_tasks())
]


def assert_same_bits(
    fused: tuple[np.ndarray, np.ndarray], oracle: tuple[np.ndarray, np.ndarray]
) -> None:
    for got, want in zip(fused, oracle, strict=True):
        assert got.shape == want.shape
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


def both(
    description: TaskDescription,
    state: TaskState,
    trials: np.ndarray | None = None,
    fixed_static_geometry: bool = False,
) -> None:
    fused = StepFeatures(description, fixed_static_geometry)
    oracle = StepFeatures(description, fixed_static_geometry, fused=False)
    assert_same_bits(
        tuple(a.copy() for a in fused.compute(state, trials)),
        tuple(a.copy() for a in oracle.compute(state, trials)),
    )


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
@pytest.mark.parametrize("n_trials", [1, 7, 130])
@pytest.mark.parametrize("p_present", [0.0, 0.5, 1.0])
def test_random_states(
    description: TaskDescription, n_trials: int, p_present: float
) -> None:
    rng = np.random.default_rng(n_trials)
    for _ in range(3):
        both(description, random_state(description, n_trials, rng, p_present=p_present))


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
def test_some_trials_and_cached_static_shapes(description: TaskDescription) -> None:
    rng = np.random.default_rng(5)
    first = random_state(description, 40, rng)
    later = random_state(description, 40, rng, step=2, previous=first)
    trials = np.array([3, 3, 17, 39, 0])
    fused = StepFeatures(description, fixed_static_geometry=True)
    oracle = StepFeatures(description, fixed_static_geometry=True, fused=False)
    for state, chosen in ((first, None), (later, trials), (later, None)):
        assert_same_bits(
            tuple(a.copy() for a in fused.compute(state, chosen)),
            tuple(a.copy() for a in oracle.compute(state, chosen)),
        )


def test_shared_arrays_points_and_degenerate_segments() -> None:
    """A batch axis of 1 (the beacon, the fence), points (no radius), a fence
    reduced to one point, and overlapping discs floored at 0."""
    state = small_state([[True, False, True], [False, False, False], [True] * 3])
    both(SMALL, state)
    robots, beacon, fence = state.groups
    point_fence = GroupState(
        fence.present, fence.attributes, segments=np.full((1, 1, 1, 2, 2), 6.0)
    )
    touching = GroupState(
        robots.present,
        robots.attributes,
        centres=np.zeros_like(robots.shapes("centres")),
        radii=robots.radii,
    )
    both(SMALL, TaskState(1, state.active, (touching, beacon, point_fence)))


def test_non_finite_values_of_present_entities_propagate_alike() -> None:
    rng = np.random.default_rng(9)
    state = random_state(PREDATOR_PREY, 6, rng, p_present=1.0)
    predators, prey, boundary = state.groups
    centres = predators.shapes("centres").copy()
    centres[0, 1, 0] = np.nan
    centres[1, 2, 1] = np.inf
    segments = boundary.shapes("segments").copy()
    segments[2, 0, 1, 0, 0] = np.nan
    odd = TaskState(
        1,
        state.active,
        (
            GroupState(
                predators.present,
                predators.attributes,
                centres=centres,
                radii=predators.radii,
            ),
            prey,
            GroupState(boundary.present, boundary.attributes, segments=segments),
        ),
    )
    both(PREDATOR_PREY, odd)


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
def test_polygons_shared_by_every_trial(description: TaskDescription) -> None:
    """Polygons with a batch axis of 1 (walls) take the loop's scalar path: the
    same bits as the oracle, NaN and infinite centres included."""
    rng = np.random.default_rng(11)
    state = random_state(description, 130, rng, p_present=0.7)
    groups = []
    for group in state.groups:
        if group.segments is not None:
            group = GroupState(
                group.present[:1],
                group.attributes[:1],
                segments=group.segments[:1].copy(),
            )
        elif group.centres is not None and group.centres.shape[0] > 1:
            centres = group.centres.copy()
            centres[0, 0, 0] = np.nan
            centres[1, 0, 1] = np.inf
            group = GroupState(
                group.present, group.attributes, centres=centres, radii=group.radii
            )
        groups.append(group)
    both(description, TaskState(1, state.active, tuple(groups)))


def shared_rows(state: TaskState) -> TaskState:
    """``state`` with a batch axis of 1 where the contract allows one: every
    presence (the first trial's, so sizes shared by every trial), radii and
    polygons; values made finite where the first trial's presence now shows
    them."""
    groups = []
    for group in state.groups:
        present = group.present[:1]
        attributes = np.nan_to_num(group.attributes)
        if group.segments is not None:
            groups.append(GroupState(present, attributes, segments=group.segments[:1]))
            continue
        radii = None if group.radii is None else group.radii[:1]
        centres = np.nan_to_num(group.shapes("centres"))
        groups.append(GroupState(present, attributes, centres=centres, radii=radii))
    return TaskState(state.step, state.active, tuple(groups))


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
@pytest.mark.parametrize("fixed_static_geometry", [False, True])
@pytest.mark.parametrize("n_trials", [1, 9])
def test_step_plans_against_the_oracle(
    description: TaskDescription, fixed_static_geometry: bool, n_trials: int
) -> None:
    """A stream whose layout changes now and then: each step of a layout after its
    first runs the plan made at that first step, on its own state's values, and
    gives the oracle's bits, with the options' features too; a static group's
    slots appearing late are read as they appear."""
    options = [SdbcOptions()]
    with contextlib.suppress(ValueError):
        extended = SdbcOptions(state_deviation=True, relations=True)
        behaviour_features(description, extended)
        options.append(extended)
    for chosen in options:
        rng = np.random.default_rng(n_trials)
        fused = StepFeatures(description, fixed_static_geometry, options=chosen)
        oracle = StepFeatures(
            description, fixed_static_geometry, fused=False, options=chosen
        )
        state: TaskState | None = None
        for step in range(1, 9):
            state = random_state(
                description, n_trials, rng, step=step, p_present=0.6, previous=state
            )
            given = shared_rows(state) if step in (3, 4, 5) else state
            assert_same_bits(
                tuple(a.copy() for a in fused.compute(given)),
                tuple(a.copy() for a in oracle.compute(given)),
            )


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
@pytest.mark.parametrize("fixed_static_geometry", [False, True])
def test_plans_of_some_trials_against_the_oracle(
    description: TaskDescription, fixed_static_geometry: bool
) -> None:
    """The whole batch, then some of its trials at each step (as the extractor
    computes them once few are left), with their plans: the oracle's bits."""
    rng = np.random.default_rng(8)
    fused = StepFeatures(description, fixed_static_geometry)
    oracle = StepFeatures(description, fixed_static_geometry, fused=False)
    some = [None, None, [1, 4, 4, 9], [0, 4, 6, 11], [3, 3, 3, 3], [2, 7], [5, 8]]
    state: TaskState | None = None
    for step, trials in enumerate(some, start=1):
        state = random_state(
            description, 12, rng, step=step, p_present=0.6, previous=state
        )
        given = shared_rows(state) if step == 5 else state
        chosen = None if trials is None else np.array(trials)
        assert_same_bits(
            tuple(a.copy() for a in fused.compute(given, chosen)),
            tuple(a.copy() for a in oracle.compute(given, chosen)),
        )
