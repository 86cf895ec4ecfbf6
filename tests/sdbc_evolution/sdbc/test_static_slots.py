"""A static group's slot that is absent, with undefined (NaN) shapes, and present
later: every path reads its shapes once it is present (issue 40's reproducer).

An Agent (a point, 1..1, moving) at (0, 0); Food (points, 0..2, static) present
[T, F], [T, T], [F, T] at (10, 0) and (20, 0), NaN where absent. The Agent-food
distance is 10, 15, 20: mean 15, final 20.
"""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.characterise.sdbc import OptionedSdbcExtractor
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.options import SdbcOptions
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)

NAN = np.nan
DESCRIPTION = TaskDescription(
    "static_slots",
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
            name="Food",
            attributes=(),
            min_size=0,
            max_size=2,
            static=True,
            geometry=Geometry.POINT,
        ),
    ),
)
PRESENT = [[True, False], [True, True], [False, True]]
CENTRES = [[(10, 0), (NAN, NAN)], [(10, 0), (20, 0)], [(NAN, NAN), (20, 0)]]
MEAN, FINAL = "Agent-food distance (M)", "Agent-food distance (F)"


def states(trials: int = 1, shared_food: bool = True) -> list[TaskState]:
    """The three steps, the same in every trial; food arrays shared by every
    trial (one row) or one row per trial."""
    rows = 1 if shared_food else trials
    return [
        TaskState(
            step=t + 1,
            active=np.ones(trials, dtype=bool),
            groups=(
                GroupState(
                    present=np.ones((1, 1), dtype=bool),
                    attributes=np.zeros((1, 1, 0)),
                    centres=np.zeros((1, 1, 2)),
                ),
                GroupState(
                    present=np.repeat(np.array([PRESENT[t]]), rows, axis=0),
                    attributes=np.zeros((rows, 2, 0)),
                    centres=np.repeat(np.array([CENTRES[t]], float), rows, axis=0),
                ),
            ),
        )
        for t in range(3)
    ]


def characterise(extractor, trials: int = 1, shared_food: bool = True) -> dict:
    extractor.start(DESCRIPTION, trials)
    for state in states(trials, shared_food):
        extractor.observe(state)
    vectors = extractor.characterisations()
    return {name: vectors[:, d] for d, name in enumerate(extractor.dimension_names)}


@pytest.mark.parametrize("check_values", [True, False])
@pytest.mark.parametrize("shared_food", [True, False])
@pytest.mark.parametrize("compact_below", [0.0, 1.0])
def test_engine_path_paper_options(check_values, shared_food, compact_below) -> None:
    extractor = SdbcExtractor(check_values=check_values, compact_below=compact_below)
    values = characterise(extractor, trials=3, shared_food=shared_food)
    np.testing.assert_array_equal(values[MEAN], [15.0] * 3)
    np.testing.assert_array_equal(values[FINAL], [20.0] * 3)


@pytest.mark.parametrize("check_values", [True, False])
@pytest.mark.parametrize(
    "options",
    [
        SdbcOptions(aggregation="mean"),
        SdbcOptions(aggregation="final"),
        SdbcOptions(aggregation="regression"),
        SdbcOptions(aggregation={"frames": 3}),
        SdbcOptions(state_deviation=True),
    ],
    ids=lambda o: str(o.aggregation) + ("+deviation" if o.state_deviation else ""),
)
def test_engine_path_with_options(check_values, options) -> None:
    values = characterise(SdbcExtractor(options, check_values=check_values))
    if options.mode in ("mean", "mean+final"):
        assert values[MEAN] == 15.0
    if options.mode in ("final", "mean+final"):
        assert values[FINAL] == 20.0
    if options.mode == "regression":
        # 10, 15, 20 over t = 1, 2, 3: the line 5 + 5 t.
        assert values["Agent-food distance (intercept)"] == pytest.approx(5.0)
        assert values["Agent-food distance (slope)"] == pytest.approx(5.0)
    if options.mode == "frames":
        frames = [values[f"Agent-food distance (frame {k}/3)"][0] for k in (1, 2, 3)]
        assert frames == [10.0, 15.0, 20.0]


def test_the_former_options_extractor() -> None:
    values = characterise(OptionedSdbcExtractor(SdbcOptions()))
    assert (values[MEAN], values[FINAL]) == (15.0, 20.0)


def test_shapes_read_every_step_without_the_cache() -> None:
    values = characterise(SdbcExtractor(fixed_static_geometry=False))
    assert (values[MEAN], values[FINAL]) == (15.0, 20.0)


def test_message_path() -> None:
    pytest.importorskip("sdbc_msgs.msg", reason="sdbc_msgs is not built")
    from sdbc_evolution.sdbc.messages import MessageSdbcExtractor
    from sdbc_sim.task_state_msgs import task_state_to_msg

    for options in (None, SdbcOptions(aggregation="mean")):
        stream = MessageSdbcExtractor(options=options)
        vector = None
        for state in states():
            msg = task_state_to_msg(
                state, DESCRIPTION, 0, 7, DESCRIPTION.name, state.step == 3
            )
            vector = stream.add(msg)
        assert vector is not None
        values = dict(zip(stream.dimension_names, vector, strict=True))
        assert values[MEAN] == 15.0
        if options is None:
            assert values[FINAL] == 20.0
