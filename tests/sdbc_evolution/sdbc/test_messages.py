"""sdbc_msgs/TaskState both ways, and SDBCs from a message stream equal to the
engine's to 1e-9."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.features import StepFeatures
from sdbc_evolution.sdbc.messages import MessageSdbcExtractor, characterise_messages
from sdbc_sim.task_state import Geometry, TaskDescription
from sdbc_sim.task_state_msgs import (
    task_description_from_msg,
    task_state_from_msg,
    task_state_to_msg,
)
from sdbc_states import (
    GATE_ESCAPE,
    PREDATOR_PREY,
    RESOURCE_SHARING,
    SMALL,
    random_state,
    small_state,
)

try:
    import sdbc_msgs.msg  # noqa: F401

    pytestmark = pytest.mark.ros
except ImportError:
    # A tests/sdbc_msgs folder can pass for the package: check the messages.
    pytestmark = [
        pytest.mark.ros,
        pytest.mark.skip(
            reason="sdbc_msgs.msg not importable: run through `scripts/sdbc test`, "
            "which builds the workspace and sets up its environment"
        ),
    ]

DESCRIPTIONS = [GATE_ESCAPE, RESOURCE_SHARING, PREDATOR_PREY, SMALL]


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
def test_round_trip_keeps_every_feature(description) -> None:
    rng = np.random.default_rng(7)
    state = random_state(description, 6, rng, step=4, p_present=0.6)
    features = StepFeatures(description)
    batch = features.values(state)
    for b in range(6):
        msg = task_state_to_msg(state, description, b, 100 + b, description.name, False)
        assert (msg.trial_id, msg.step, msg.done, msg.task) == (
            100 + b,
            4,
            False,
            description.name,
        )
        assert msg.header.frame_id == "arena"
        back = task_state_from_msg(msg, description)
        np.testing.assert_allclose(
            features.values(back)[0], batch[b], rtol=1e-12, atol=1e-12
        )


def test_message_lists_present_entities_only() -> None:
    state = small_state([[True, False, True]])
    msg = task_state_to_msg(state, SMALL, 0, 1, "small", True)
    robots, beacon, fence = msg.groups
    assert [list(e.state) for e in robots.entities] == [[2.0], [4.0]]
    assert [(e.centre.x, e.centre.y, e.radius) for e in robots.entities] == [
        (0.0, 0.0, 1.0),
        (6.0, 8.0, 1.0),
    ]
    assert (robots.name, list(robots.attribute_names)) == ("Robots", ["speed"])
    assert (robots.min_size, robots.max_size, robots.is_static) == (0, 3, False)
    assert beacon.entities[0].geometry == 1  # GEOMETRY_POINT
    assert [(p.x, p.y) for p in fence.entities[0].segments] == [
        (-10.0, -3.0),
        (20.0, -3.0),
    ]


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=lambda d: d.name)
def test_description_from_a_message(description) -> None:
    state = random_state(description, 1, np.random.default_rng(1), p_present=1.0)
    msg = task_state_to_msg(state, description, 0, 1, description.name, False)
    assert task_description_from_msg(msg) == description


def test_an_empty_group_needs_its_geometry_named() -> None:
    msg = task_state_to_msg(
        small_state([[False, False, False]]), SMALL, 0, 1, "small", False
    )
    with pytest.raises(ValueError, match="group 'Robots' is empty in this message"):
        task_description_from_msg(msg)
    described = task_description_from_msg(msg, {"Robots": Geometry.CIRCLE})
    assert described == SMALL


def test_bad_descriptions_in_messages_are_named() -> None:
    msg = task_state_to_msg(
        small_state([[True, True, True]]), SMALL, 0, 1, "small", False
    )
    msg.groups[0].min_size = 5
    with pytest.raises(ValueError, match=r"'Robots': min_size 5 > max_size 3"):
        task_description_from_msg(msg)
    msg.groups[0].min_size = 0
    msg.groups[1].name = "Robots"
    with pytest.raises(ValueError, match=r"duplicate group names \['Robots'\]"):
        task_description_from_msg(msg)


def message(present=((True, True, True),)):
    return task_state_to_msg(
        small_state([list(present[0])]), SMALL, 0, 5, "small", False
    )


def test_wrong_state_length_is_named() -> None:
    msg = message()
    msg.groups[0].entities[1].state = [1.0, 2.0]
    with pytest.raises(
        ValueError, match=r"group 'Robots', entity 1: state has 2 values, expected 1"
    ):
        task_state_from_msg(msg, SMALL)


@pytest.mark.parametrize(
    ("mutate", "message_pattern"),
    [
        (lambda m: m.groups.pop(), "2 groups in the message, 3 in the description"),
        (
            lambda m: setattr(m.groups[0], "max_size", 4),
            "group 'Robots': max_size is 4, the description says 3",
        ),
        (
            lambda m: setattr(m.groups[1], "name", "Lamp"),
            "name is 'Lamp', the description says 'Beacon'",
        ),
        (
            lambda m: m.groups[0].entities.append(m.groups[0].entities[0]),
            "group 'Robots': 4 entities, outside its limits",
        ),
        (
            lambda m: setattr(m.groups[0].entities[0], "geometry", 2),
            "entity 0: geometry 2, the description says 0",
        ),
        (
            lambda m: m.groups[2].entities[0].segments.pop(),
            "1 segment end points",
        ),
        (
            lambda m: setattr(m.groups[0].entities[2].centre, "x", math.nan),
            "entity 2: state or centre is not finite",
        ),
        (
            lambda m: setattr(m.groups[0].entities[0], "radius", -1.0),
            "radius is negative",
        ),
    ],
)
def test_malformed_messages_are_named(mutate, message_pattern: str) -> None:
    msg = message()
    mutate(msg)
    with pytest.raises(ValueError, match=message_pattern):
        task_state_from_msg(msg, SMALL)


def test_polygons_with_different_segment_counts() -> None:
    from geometry_msgs.msg import Point

    from sdbc_msgs.msg import Entity, EntityGroup
    from sdbc_msgs.msg import TaskState as TaskStateMsg

    def polygon(*points):
        return Entity(geometry=2, segments=[Point(x=x, y=y) for x, y in points])

    msg = TaskStateMsg(task="walls", trial_id=1, step=1)
    msg.groups = [
        EntityGroup(
            name="Ball",
            min_size=1,
            max_size=1,
            entities=[Entity(geometry=0, centre=Point(x=0.0, y=0.0), radius=1.0)],
        ),
        EntityGroup(
            name="Walls",
            min_size=2,
            max_size=2,
            is_static=True,
            # One segment 5 away; three segments, the nearest 3 away.
            entities=[
                polygon((5, -1), (5, 1)),
                polygon((-9, 9), (9, 9), (9, 9), (9, -9), (-3, -9), (-3, 9)),
            ],
        ),
    ]
    description = task_description_from_msg(msg)
    state = task_state_from_msg(msg, description)
    assert state.groups[1].segments.shape == (1, 2, 3, 2, 2)
    # Ball-walls distance: mean of (5 - 1) and (3 - 1).
    np.testing.assert_allclose(StepFeatures(description).values(state), [[3.0]])


def test_stream_of_interleaved_trials() -> None:
    rng = np.random.default_rng(5)
    lengths = {7: 3, 8: 5}
    states = [random_state(PREDATOR_PREY, 2, rng, step=1)]
    for k in range(2, 6):
        states.append(random_state(PREDATOR_PREY, 2, rng, step=k, previous=states[-1]))
    reference = SdbcExtractor()
    reference.start(PREDATOR_PREY, 2)
    messages = []
    for k, state in enumerate(states, start=1):
        state.active = np.array([k <= lengths[7], k <= lengths[8]])
        reference.observe(state)
        for b, trial_id in enumerate((7, 8)):
            if k <= lengths[trial_id]:
                done = k == lengths[trial_id]
                msg = task_state_to_msg(state, PREDATOR_PREY, b, trial_id, "pp", done)
                messages.append(msg)
    extractor = MessageSdbcExtractor(PREDATOR_PREY)
    vectors = {}
    for msg in messages:
        vector = extractor.add(msg)
        if vector is not None:
            vectors[msg.trial_id] = vector
        assert (vector is not None) == msg.done
    assert extractor.open_trials == ()
    expected = reference.characterisations()
    np.testing.assert_allclose(vectors[7], expected[0], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(vectors[8], expected[1], rtol=1e-12, atol=1e-9)
    # The description can come from the stream itself.
    from_stream = characterise_messages(messages)
    np.testing.assert_array_equal(from_stream[7], vectors[7])
    assert (
        MessageSdbcExtractor(PREDATOR_PREY).dimension_names == reference.dimension_names
    )


def test_a_stream_must_start_at_step_one_and_not_skip() -> None:
    rng = np.random.default_rng(6)
    state = random_state(SMALL, 1, rng)
    extractor = MessageSdbcExtractor(SMALL)
    state.step = 2
    with pytest.raises(ValueError, match="first message is step 2"):
        extractor.add(task_state_to_msg(state, SMALL, 0, 3, "small", False))
    state.step = 1
    extractor.add(task_state_to_msg(state, SMALL, 0, 3, "small", False))
    state.step = 3
    with pytest.raises(ValueError, match="step 3 follows step 1"):
        extractor.add(task_state_to_msg(state, SMALL, 0, 3, "small", False))


def test_to_msg_checks_its_arguments() -> None:
    state = small_state([[True, True, True]])
    with pytest.raises(ValueError, match="trial index 1 outside 0..0"):
        task_state_to_msg(state, SMALL, 1, 1, "small", False)
    with pytest.raises(ValueError, match="3 groups in the state, 2 in the description"):
        task_state_to_msg(
            state, TaskDescription("x", SMALL.groups[:2]), 0, 1, "", False
        )


class MessageRecorder:
    """An engine observer that publishes nothing but keeps every active trial's
    messages, as a simulator node would publish them."""

    def start(self, description, n_trials: int) -> None:
        self.description = description
        self.messages: list[list] = [[] for _ in range(n_trials)]

    def observe(self, state) -> None:
        for b in np.flatnonzero(state.active):
            self.messages[b].append(
                task_state_to_msg(state, self.description, b, b, "engine", False)
            )


@pytest.mark.parametrize(
    "task_name",
    ["gate_escape", "resource_sharing", "predator_prey", "aggregation", "foraging"],
)
def test_engine_trials_give_the_same_vector_as_their_messages(task_name: str) -> None:
    from sdbc_sim.engine import run_batch
    from sdbc_sim.tasks import available_tasks, make_task

    if task_name not in available_tasks():
        pytest.skip(f"task {task_name} not in this checkout")
    task = make_task(task_name, max_steps=150)
    rng = np.random.default_rng(8)
    genomes = rng.uniform(-1.0, 1.0, (2, task.genome_length))
    seeds = rng.integers(0, 2**31, (2, 2))
    extractor, recorder = SdbcExtractor(), MessageRecorder()
    result = run_batch(task, genomes, seeds, [extractor, recorder])
    batch_vectors = extractor.characterisations()
    np.testing.assert_array_equal(batch_vectors[:, -1], result.length.reshape(-1))
    stream = MessageSdbcExtractor(task.description)
    for b, messages in enumerate(recorder.messages):
        messages[-1].done = True
        vectors = [stream.add(m) for m in messages]
        assert all(v is None for v in vectors[:-1])
        np.testing.assert_allclose(vectors[-1], batch_vectors[b], rtol=0, atol=1e-9)
    # The last trial run alone, in a batch of one, gives the same vector too.
    alone = SdbcExtractor()
    run_batch(task, genomes[1:], seeds[1:, 1:], [alone])
    np.testing.assert_allclose(
        alone.characterisations()[0], batch_vectors[3], rtol=0, atol=1e-9
    )
