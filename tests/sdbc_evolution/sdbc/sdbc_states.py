"""Hand-made task descriptions and task states for the SDBC tests.

The descriptions follow the three tasks of docs/reference-setup.md, written out here
so that the SDBC can be tested without the engine; tests against the real tasks are in
test_task_characterisations.py.
"""

from __future__ import annotations

import numpy as np
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)

MOVING = ("x", "y", "turning speed", "linear speed")

GATE_ESCAPE = TaskDescription(
    "gate_escape",
    (
        EntityGroupSpec(
            name="Agent",
            attributes=(*MOVING, "is passing gate"),
            min_size=0,
            max_size=4,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Gate",
            attributes=("is closing",),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.POLYGON,
        ),
        EntityGroupSpec(
            name="Wall",
            attributes=(),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.POLYGON,
        ),
    ),
)

RESOURCE_SHARING = TaskDescription(
    "resource_sharing",
    (
        EntityGroupSpec(
            name="Agent",
            attributes=(*MOVING, "energy level", "is charging"),
            min_size=0,
            max_size=3,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Station",
            attributes=("is occupied",),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.CIRCLE,
        ),
    ),
)

PREDATOR_PREY = TaskDescription(
    "predator_prey",
    (
        EntityGroupSpec(
            name="Predators",
            attributes=MOVING,
            min_size=3,
            max_size=3,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Prey",
            attributes=MOVING,
            min_size=0,
            max_size=1,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Boundary",
            attributes=(),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.POLYGON,
        ),
    ),
)

# Robots (circles, 0..3, moving), a Beacon (point, static), a Fence (polygon, static).
SMALL = TaskDescription(
    "small",
    (
        EntityGroupSpec(
            name="Robots",
            attributes=("speed",),
            min_size=0,
            max_size=3,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Beacon",
            attributes=("is on",),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.POINT,
        ),
        EntityGroupSpec(
            name="Fence",
            attributes=(),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.POLYGON,
        ),
    ),
)
SMALL_NAMES = [
    "Robots group size",
    "Robots speed",
    "Robots dispersion",
    "Robots-beacon distance",
    "Robots-fence distance",
    "Beacon is on",
]


def small_state(present: list[list[bool]]) -> TaskState:
    """Trials of SMALL: robots at (0, 0), (99, 99) and (6, 8), radius 1, speeds 2,
    7 and 4, the ones in ``present`` there (absent slots hold NaN); the beacon at
    (0, 10), on; the fence the line y = -3 from x = -10 to 20, shared by all trials."""
    p = np.array(present, dtype=bool)
    b = p.shape[0]
    centres = np.broadcast_to(
        np.array([[0.0, 0.0], [99.0, 99.0], [6.0, 8.0]]), (b, 3, 2)
    )
    centres = np.where(p[..., None], centres, np.nan)
    speeds = np.where(p, np.array([2.0, 7.0, 4.0]), np.nan)[..., None]
    robots = GroupState(p, speeds, centres=centres, radii=np.ones((b, 3)))
    beacon = GroupState(
        np.ones((1, 1), bool), np.ones((b, 1, 1)), centres=np.array([[[0.0, 10.0]]])
    )
    fence = GroupState(
        np.ones((1, 1), bool),
        np.empty((1, 1, 0)),
        segments=np.array([[[[[-10.0, -3.0], [20.0, -3.0]]]]]),
    )
    return TaskState(1, np.ones(b, bool), (robots, beacon, fence))


SQUARE = np.array(
    [
        [[0.0, 0.0], [10.0, 0.0]],
        [[10.0, 0.0], [10.0, 10.0]],
        [[10.0, 10.0], [0.0, 10.0]],
        [[0.0, 10.0], [0.0, 0.0]],
    ]
)
"""A 10 x 10 boundary as four segments."""


def random_state(
    description: TaskDescription,
    n_trials: int,
    rng: np.random.Generator,
    step: int = 1,
    n_segments: int = 3,
    p_present: float = 0.8,
    previous: TaskState | None = None,
) -> TaskState:
    """A random but valid task state: sizes within limits, finite values where
    present and NaN garbage where absent (which must never leak into a feature).
    Static groups keep the geometry of the ``previous`` step's state, if given."""
    groups = []
    for k, spec in enumerate(description.groups):
        s, a = spec.max_size, len(spec.attributes)
        present = rng.random((n_trials, s)) < p_present
        # Honour min_size: the first min_size slots are always filled.
        present[:, : spec.min_size] = True
        attributes = rng.normal(size=(n_trials, s, a))
        attributes[~present] = np.nan
        if spec.geometry is Geometry.POLYGON:
            segments = rng.uniform(-20.0, 20.0, (n_trials, s, n_segments, 2, 2))
            if previous is not None and spec.is_static:
                segments = previous.groups[k].segments
            groups.append(GroupState(present, attributes, segments=segments))
            continue
        centres = rng.uniform(-20.0, 20.0, (n_trials, s, 2))
        centres[~present] = np.nan
        radii = (
            rng.uniform(0.5, 3.0, (n_trials, s))
            if spec.geometry is Geometry.CIRCLE
            else None
        )
        if previous is not None and spec.is_static:
            centres, radii = previous.groups[k].centres, previous.groups[k].radii
        groups.append(GroupState(present, attributes, centres=centres, radii=radii))
    return TaskState(step, np.ones(n_trials, dtype=bool), tuple(groups))


def trial_of(state: TaskState, index: int) -> TaskState:
    """Trial ``index`` of a batch as a batch of one (shared arrays stay shared)."""

    def one(array: np.ndarray | None) -> np.ndarray | None:
        if array is None or array.shape[0] == 1:
            return array
        return array[index : index + 1].copy()

    groups = tuple(
        GroupState(
            one(g.present),
            one(g.attributes),
            one(g.centres),
            one(g.radii),
            one(g.segments),
        )
        for g in state.groups
    )
    return TaskState(state.step, state.active[index : index + 1].copy(), groups)
