"""Per-step features (eqs. 2 to 5) against hand-computed values, and their layout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.features import (
    FeatureKind,
    StepFeatures,
    behaviour_features,
)
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
    validate_task_state,
)
from sdbc_states import (
    GATE_ESCAPE,
    PREDATOR_PREY,
    RESOURCE_SHARING,
    SMALL,
    SMALL_NAMES,
    random_state,
    small_state,
    trial_of,
)

NAN = math.nan


def test_small_layout() -> None:
    features = behaviour_features(SMALL)
    assert [f.name for f in features] == SMALL_NAMES
    assert [f.kind for f in features] == [
        FeatureKind.GROUP_SIZE,
        FeatureKind.MEAN_STATE,
        FeatureKind.DISPERSION,
        FeatureKind.GROUP_DISTANCE,
        FeatureKind.GROUP_DISTANCE,
        FeatureKind.MEAN_STATE,
    ]


def test_hand_computed_values() -> None:
    # Trial 0: robots 0 and 2; trial 1: none (empty group); trial 2: robot 2 only.
    state = small_state(
        [[True, False, True], [False, False, False], [False, False, True]]
    )
    values = StepFeatures(SMALL).values(state)
    d_beacon_0 = 10.0 - 1.0  # robot 0 to (0, 10), minus its radius
    d_beacon_2 = math.sqrt(6**2 + 2**2) - 1.0
    expected = np.array(
        [
            # size 2/3; speed (2+4)/2; dispersion |(6,8)| - 2 radii = 8;
            # beacon mean of the two; fence (3-1 + 11-1)/2; the beacon is on.
            [2 / 3, 3.0, 8.0, (d_beacon_0 + d_beacon_2) / 2, 6.0, 1.0],
            # Empty group: size 0, everything else of the group undefined.
            [0.0, NAN, NAN, NAN, NAN, 1.0],
            # One robot: no pair, so no dispersion.
            [1 / 3, 4.0, NAN, d_beacon_2, 10.0, 1.0],
        ]
    )
    np.testing.assert_allclose(values, expected, rtol=0, atol=1e-12)


def test_dispersion_is_the_mean_over_pairs() -> None:
    # Three points 5, 5 and 10 apart: the mean over pairs is 20/3 (the paper's
    # printed eq. 4, dividing by (|g| - 1)^2, would give 10).
    description = TaskDescription(
        "points",
        (
            EntityGroupSpec(
                name="Dots",
                attributes=(),
                min_size=0,
                max_size=3,
                static=False,
                geometry=Geometry.POINT,
            ),
        ),
    )
    centres = np.array([[[0.0, 0.0], [3.0, 4.0], [6.0, 8.0]]])
    state = TaskState(
        1,
        np.ones(1, bool),
        (GroupState(np.ones((1, 3), bool), np.empty((1, 3, 0)), centres=centres),),
    )
    values = StepFeatures(description).values(state)
    assert [f.name for f in behaviour_features(description)] == [
        "Dots group size",
        "Dots dispersion",
    ]
    np.testing.assert_allclose(values, [[1.0, 20.0 / 3.0]])


def test_moving_polygons() -> None:
    # Two moving doors (segments 3 apart) and a circle: dispersion between polygons
    # and the circle-polygon group distance.
    description = TaskDescription(
        "doors",
        (
            EntityGroupSpec(
                name="Doors",
                attributes=("open",),
                min_size=2,
                max_size=2,
                static=False,
                geometry=Geometry.POLYGON,
            ),
            EntityGroupSpec(
                name="Ball",
                attributes=(),
                min_size=1,
                max_size=1,
                static=False,
                geometry=Geometry.CIRCLE,
            ),
        ),
    )
    doors = np.array([[[[[0.0, 0.0], [1.0, 0.0]]], [[[0.0, 3.0], [1.0, 3.0]]]]])
    state = TaskState(
        1,
        np.ones(1, bool),
        (
            GroupState(
                np.ones((1, 2), bool), np.array([[[0.0], [1.0]]]), segments=doors
            ),
            GroupState(
                np.ones((1, 1), bool),
                np.empty((1, 1, 0)),
                centres=np.array([[[0.5, 1.0]]]),
                radii=np.array([[0.25]]),
            ),
        ),
    )
    names = [f.name for f in behaviour_features(description)]
    assert names == ["Doors open", "Doors dispersion", "Doors-ball distance"]
    # The ball is 1 from the lower door and 2 from the upper one, minus 0.25.
    np.testing.assert_allclose(
        StepFeatures(description).values(state), [[0.5, 3.0, 1.25]]
    )


def test_structural_exclusions() -> None:
    description = TaskDescription(
        "exclusions",
        (
            # min = max: no size. max = 1: no dispersion.
            EntityGroupSpec(
                name="Solo",
                attributes=("a",),
                min_size=1,
                max_size=1,
                static=False,
                geometry=Geometry.CIRCLE,
            ),
            # Static, several entities: no dispersion.
            EntityGroupSpec(
                name="Posts",
                attributes=(),
                min_size=2,
                max_size=5,
                static=True,
                geometry=Geometry.POINT,
            ),
            # Static too: no Posts-lamps distance.
            EntityGroupSpec(
                name="Lamps",
                attributes=("lit",),
                min_size=0,
                max_size=2,
                static=True,
                geometry=Geometry.POINT,
            ),
        ),
    )
    assert [f.name for f in behaviour_features(description)] == [
        "Solo a",
        "Solo-posts distance",
        "Solo-lamps distance",
        "Posts group size",
        "Lamps group size",
        "Lamps lit",
    ]


@pytest.mark.parametrize(
    ("description", "names"),
    [
        (
            GATE_ESCAPE,
            [
                "Agent group size",
                "Agent x",
                "Agent y",
                "Agent turning speed",
                "Agent linear speed",
                "Agent is passing gate",
                "Agent dispersion",
                "Agent-gate distance",
                "Agent-wall distance",
                "Gate is closing",
            ],
        ),
        (
            RESOURCE_SHARING,
            [
                "Agent group size",
                "Agent x",
                "Agent y",
                "Agent turning speed",
                "Agent linear speed",
                "Agent energy level",
                "Agent is charging",
                "Agent dispersion",
                "Agent-station distance",
                "Station is occupied",
            ],
        ),
        (
            PREDATOR_PREY,
            [
                "Predators x",
                "Predators y",
                "Predators turning speed",
                "Predators linear speed",
                "Predators dispersion",
                "Predators-prey distance",
                "Predators-boundary distance",
                "Prey group size",
                "Prey x",
                "Prey y",
                "Prey turning speed",
                "Prey linear speed",
                "Prey-boundary distance",
            ],
        ),
    ],
)
def test_paper_task_features(description: TaskDescription, names: list[str]) -> None:
    assert [f.name for f in behaviour_features(description)] == names


def test_acronym_group_names_keep_their_case() -> None:
    description = TaskDescription(
        "acronym",
        (
            EntityGroupSpec(
                name="Robot",
                attributes=(),
                min_size=1,
                max_size=1,
                static=False,
                geometry=Geometry.POINT,
            ),
            EntityGroupSpec(
                name="GPS beacon",
                attributes=(),
                min_size=1,
                max_size=1,
                static=True,
                geometry=Geometry.POINT,
            ),
        ),
    )
    assert [f.name for f in behaviour_features(description)] == [
        "Robot-GPS beacon distance"
    ]


def test_clashing_feature_names_are_an_error() -> None:
    description = TaskDescription(
        "clash",
        (
            EntityGroupSpec(
                name="Agent",
                attributes=("dispersion",),
                min_size=0,
                max_size=2,
                static=False,
                geometry=Geometry.POINT,
            ),
        ),
    )
    with pytest.raises(ValueError, match=r"'Agent dispersion'"):
        behaviour_features(description)


def test_a_trial_computes_the_same_alone_and_in_a_batch() -> None:
    rng = np.random.default_rng(3)
    for description in (GATE_ESCAPE, RESOURCE_SHARING, PREDATOR_PREY):
        state = random_state(description, 9, rng)
        extractor = StepFeatures(description)
        batch = extractor.values(state)
        for b in range(9):
            np.testing.assert_array_equal(
                extractor.values(trial_of(state, b))[0], batch[b]
            )


def test_nan_in_absent_slots_never_leaks() -> None:
    rng = np.random.default_rng(4)
    state = random_state(PREDATOR_PREY, 50, rng, p_present=0.5)
    values = StepFeatures(PREDATOR_PREY).values(state)
    prey_present = state.groups[1].present[:, 0]
    # Predators are always all there: their own features and their distance to the
    # boundary are always defined, and so is the prey's group size.
    always = [0, 1, 2, 3, 4, 6, 7]
    assert np.isfinite(values[:, always]).all()
    # Everything involving the prey is defined exactly when the prey is there.
    with_prey = [5, 8, 9, 10, 11, 12]
    np.testing.assert_array_equal(
        np.isfinite(values[:, with_prey]).all(axis=1), prey_present
    )
    np.testing.assert_array_equal(
        np.isnan(values[:, with_prey]).all(axis=1), ~prey_present
    )


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (
            lambda s: s.groups[0].__setattr__("present", s.groups[0].present[:, :2]),
            "present",
        ),
        (
            lambda s: s.groups[0].__setattr__("attributes", np.zeros((2, 3, 2))),
            "attributes",
        ),
        (lambda s: s.groups[0].__setattr__("radii", None), "radii is missing"),
        (
            lambda s: s.groups[2].__setattr__("segments", np.zeros((1, 1, 2, 2))),
            "segments",
        ),
        (
            lambda s: s.groups[0].__setattr__(
                "centres", s.groups[0].centres.astype(np.float32)
            ),
            "dtype float32",
        ),
        (lambda s: s.__setattr__("groups", s.groups[:2]), "2 groups in the state"),
        (lambda s: s.__setattr__("active", np.ones(3, bool)), "active"),
    ],
)
def test_malformed_states_are_named(mutate, message: str) -> None:
    state = small_state([[True, True, True], [True, False, False]])
    mutate(state)
    with pytest.raises(ValueError, match=message):
        validate_task_state(SMALL, state, 2)


def test_bad_task_descriptions_are_named() -> None:
    with pytest.raises(ValueError, match=r"'Agent': min_size 3 > max_size 2"):
        EntityGroupSpec(
            name="Agent",
            attributes=("x",),
            min_size=3,
            max_size=2,
            static=False,
            geometry=Geometry.CIRCLE,
        )
    agent = EntityGroupSpec(
        name="Agent",
        attributes=("x",),
        min_size=0,
        max_size=2,
        static=False,
        geometry=Geometry.CIRCLE,
    )
    with pytest.raises(ValueError, match=r"duplicate group names \['Agent'\]"):
        TaskDescription("twice", (agent, agent))
