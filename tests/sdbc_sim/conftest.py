"""Helpers for engine and task tests: tasks started from hand-placed robots."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from sdbc_sim.task import Task


def _place(task: Task, position: np.ndarray, angle: np.ndarray) -> Task:
    position = np.asarray(position, dtype=np.float64)
    angle = np.asarray(angle, dtype=np.float64)
    draw = task.reset

    def reset(rngs: list[np.random.Generator]):
        trials, _, _ = draw(rngs)
        b = len(rngs)
        return trials, np.repeat(position[None], b, 0), np.repeat(angle[None], b, 0)

    task.reset = reset  # type: ignore[method-assign]
    return task


@pytest.fixture
def placed() -> Callable[[Task, np.ndarray, np.ndarray], Task]:
    """``placed(task, position, angle)``: ``task`` with every trial starting from
    ``position`` (R, 2) and ``angle`` (R,) instead of random ones."""
    return _place


@pytest.fixture
def pushing_crowd() -> Task:
    """Gate escape with 8 robots in a 60 x 60 arena and the gate open for its
    1000 steps: robots under random outputs keep running into each other and the
    walls (the physics models' overlap tests)."""
    from sdbc_sim.tasks import make_task

    return make_task(
        "gate_escape",
        arena_size=60.0,
        n_robots=8,
        start_spacing=6.0,
        max_steps=1000,
        gate_closing_steps=1000,
    )
