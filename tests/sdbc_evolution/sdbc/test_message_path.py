"""The message path gives the engine path's vector for every task state a message
can carry: static groups whose membership changes, groups empty at step 1 (whose
geometry the stream must learn later), interleaved trials of different lengths."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.messages import (
    IncompleteTrials,
    MessageSdbcExtractor,
    characterise_messages,
)
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)
from sdbc_sim.task_state_msgs import task_state_to_msg
from sdbc_states import GATE_ESCAPE, PREDATOR_PREY, RESOURCE_SHARING, SMALL

try:
    import sdbc_msgs.msg  # noqa: F401

    pytestmark = pytest.mark.ros
except ImportError:
    pytestmark = [
        pytest.mark.ros,
        pytest.mark.skip(reason="sdbc_msgs.msg not importable: use scripts/sdbc test"),
    ]

# Food items (static points) eaten and a shrinking set of walls (static polygons)
# of any size from 0: the membership of static groups changes, and any of them can
# be empty at step 1.
FORAGING = TaskDescription(
    "foraging",
    (
        EntityGroupSpec(
            name="Forager",
            attributes=("x", "y", "load"),
            min_size=1,
            max_size=3,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Food",
            attributes=("calories",),
            min_size=0,
            max_size=4,
            static=True,
            geometry=Geometry.POINT,
        ),
        EntityGroupSpec(
            name="Nest",
            attributes=("stock",),
            min_size=0,
            max_size=2,
            static=True,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Walls",
            attributes=(),
            min_size=0,
            max_size=3,
            static=True,
            geometry=Geometry.POLYGON,
        ),
        EntityGroupSpec(
            name="Shadow",
            attributes=("x",),
            min_size=0,
            max_size=2,
            static=False,
            geometry=Geometry.POINT,
        ),
    ),
)
DESCRIPTIONS = [GATE_ESCAPE, RESOURCE_SHARING, PREDATOR_PREY, SMALL, FORAGING]


def random_trials(
    description: TaskDescription,
    rng: np.random.Generator,
    lengths: list[int],
    p_present: float,
    empty_first: bool,
) -> list[TaskState]:
    """States of len(lengths) trials over max(lengths) steps. Static groups keep
    each slot's shape for the whole trial (as the engine does) while their entities
    come and go; absent slots hold NaN attributes. With ``empty_first``, every group
    that may be empty is empty at step 1."""
    b = len(lengths)
    static_shapes = {}
    for g, spec in enumerate(description.groups):
        if spec.is_static:
            s = spec.max_size
            static_shapes[g] = (
                rng.uniform(-20.0, 20.0, (b, s, 2)),
                rng.uniform(0.5, 3.0, (b, s)),
                rng.uniform(-20.0, 20.0, (b, s, 2, 2, 2)),
            )
    states = []
    for step in range(1, max(lengths) + 1):
        groups = []
        for g, spec in enumerate(description.groups):
            s, a = spec.max_size, len(spec.attributes)
            present = rng.random((b, s)) < p_present
            present[:, : spec.min_size] = True
            if empty_first and step == 1 and spec.min_size == 0:
                present[:] = False
            attributes = rng.normal(size=(b, s, a))
            attributes[~present] = np.nan
            if spec.is_static:
                centres, radii, segments = static_shapes[g]
            else:
                centres = rng.uniform(-20.0, 20.0, (b, s, 2))
                centres[~present] = np.nan
                radii = rng.uniform(0.5, 3.0, (b, s))
                segments = rng.uniform(-20.0, 20.0, (b, s, 2, 2, 2))
            if spec.geometry is Geometry.POLYGON:
                groups.append(GroupState(present, attributes, segments=segments))
            elif spec.geometry is Geometry.POINT:
                groups.append(GroupState(present, attributes, centres=centres))
            else:
                groups.append(
                    GroupState(present, attributes, centres=centres, radii=radii)
                )
        active = np.array([step <= n for n in lengths])
        states.append(TaskState(step, active, tuple(groups)))
    return states


def both_paths(
    description: TaskDescription, states: list[TaskState], lengths: list[int]
) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """The engine path's (B, D) vectors and the message path's, by trial id
    (trial b has id 100 + b); the messages of all trials interleave."""
    engine = SdbcExtractor()
    engine.start(description, len(lengths))
    messages = []
    for state in states:
        engine.observe(state)
        for b in np.flatnonzero(state.active):
            done = state.step == lengths[b]
            messages.append(
                task_state_to_msg(
                    state, description, b, 100 + b, description.name, done
                )
            )
    return engine.characterisations(), characterise_messages(messages)


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(DESCRIPTIONS),
    st.integers(0, 2**32 - 1),
    st.lists(st.integers(1, 7), min_size=1, max_size=4),
    st.floats(0.0, 1.0),
    st.booleans(),
)
def test_message_path_equals_engine_path(
    description: TaskDescription,
    seed: int,
    lengths: list[int],
    p_present: float,
    empty_first: bool,
) -> None:
    rng = np.random.default_rng(seed)
    states = random_trials(description, rng, lengths, p_present, empty_first)
    expected, vectors = both_paths(description, states, lengths)
    assert sorted(vectors) == [100 + b for b in range(len(lengths))]
    for b in range(len(lengths)):
        np.testing.assert_allclose(vectors[100 + b], expected[b], rtol=1e-9, atol=1e-9)


# The worked example: an agent at (0, 0); a static group of points at (10, 0) and
# (20, 0), then only (20, 0). The agent-group distance is the mean over the group's
# entities: 15 then 20, so mean 17.5 and final 20.
EXAMPLE = TaskDescription(
    "example",
    (
        EntityGroupSpec(
            name="Agent",
            attributes=(),
            min_size=1,
            max_size=1,
            static=False,
            geometry=Geometry.POINT,
        ),
        EntityGroupSpec(
            name="Targets",
            attributes=(),
            min_size=0,
            max_size=2,
            static=True,
            geometry=Geometry.POINT,
        ),
    ),
)


def example_states(empty_first: bool) -> list[TaskState]:
    agent = GroupState(
        np.ones((1, 1), bool), np.empty((1, 1, 0)), centres=np.zeros((1, 1, 2))
    )
    targets = np.array([[[10.0, 0.0], [20.0, 0.0]]])
    presence = [[True, True], [False, True]]
    if empty_first:
        presence.insert(0, [False, False])
    return [
        TaskState(
            k,
            np.ones(1, bool),
            (
                agent,
                GroupState(np.array([present]), np.empty((1, 2, 0)), centres=targets),
            ),
        )
        for k, present in enumerate(presence, start=1)
    ]


@pytest.mark.parametrize("empty_first", [False, True], ids=["full", "empty-first"])
def test_worked_example(empty_first: bool) -> None:
    states = example_states(empty_first)
    expected, vectors = both_paths(EXAMPLE, states, [len(states)])
    names = MessageSdbcExtractor(EXAMPLE).dimension_names
    distance = {
        "mean": names.index("Agent-targets distance (M)"),
        "final": names.index("Agent-targets distance (F)"),
    }
    # Steps with the group empty add no distance to the mean (its count is 0).
    assert expected[0, distance["mean"]] == pytest.approx(17.5)
    assert expected[0, distance["final"]] == pytest.approx(20.0)
    np.testing.assert_allclose(vectors[100], expected[0], rtol=1e-12, atol=1e-12)


def test_geometry_is_learnt_from_the_first_entity() -> None:
    states = example_states(empty_first=True)
    extractor = MessageSdbcExtractor()
    msgs = [
        task_state_to_msg(s, EXAMPLE, 0, 1, "example", k == len(states))
        for k, s in enumerate(states, start=1)
    ]
    extractor.add(msgs[0])
    assert extractor.unknown_geometries == ("Targets",)
    extractor.add(msgs[1])
    assert extractor.unknown_geometries == ()
    assert extractor.description == EXAMPLE


def test_incomplete_trials_are_named() -> None:
    states = example_states(empty_first=False)
    msgs = [
        task_state_to_msg(s, EXAMPLE, 0, trial, "example", trial == 4 and k == 2)
        for k, s in enumerate(states, start=1)
        for trial in (3, 4, 5)
    ]
    with pytest.raises(
        IncompleteTrials,
        match=r"2 incomplete trial\(s\).*trial 3 \(2 steps\), trial 5 \(2 steps\)",
    ) as caught:
        characterise_messages(msgs[:-1] + [msgs[-1]])
    assert caught.value.steps == {3: 2, 5: 2}
    # One message of trial 5 lost at the end: 1 step.
    with pytest.raises(IncompleteTrials, match=r"trial 5 \(1 step\)"):
        characterise_messages(
            [m for m in msgs if not (m.trial_id == 5 and m.step == 2)]
        )
