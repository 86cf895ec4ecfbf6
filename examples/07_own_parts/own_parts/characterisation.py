"""Where a group ends up: the mean position of a moving entity group's entities at
the last step of each trial (Lehman & Stanley's end-point characterisation of maze
navigation, 2011, for a team).

It reads only the task state, so it works for any task whose description has a
moving group of circles or points.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sdbc_evolution.characterise.base import Characteriser, per_controller
from sdbc_sim.settings import settings
from sdbc_sim.task_state import Geometry, TaskDescription, TaskState


@settings
class FinalPositionOptions:
    """Which group's final position."""

    group: str | None = None
    """The entity group; None: the task's first moving group of circles or points."""


def _group_index(description: TaskDescription, group: str | None) -> int:
    """The index of the group to follow, refused in one line naming the problem."""
    moving = [
        i
        for i, g in enumerate(description.groups)
        if not g.static and g.geometry in (Geometry.CIRCLE, Geometry.POINT)
    ]
    names = [description.groups[i].name for i in moving]
    if group is None and moving:
        return moving[0]
    if group in names:
        return moving[names.index(group)]
    raise ValueError(
        f"final_position: task {description.name!r} has no moving group of circles "
        f"or points {'' if group is None else repr(group) + ' '}(it has {names})"
    )


class FinalPosition(Characteriser):
    """The mean final position of a moving group's entities."""

    options_class = FinalPositionOptions
    # Its vectors are per_controller of its trials' (the contract test checks it),
    # so a run may evaluate a generation and a re-evaluation in one batch.
    mean_of_trials = True

    def names(self, task: Any) -> tuple[str, ...]:
        description = task.description
        name = description.groups[_group_index(description, self.options.group)].name
        return (f"{name} final x", f"{name} final y")

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self._index = _group_index(description, self.options.group)
        # (0, 0) stays for a trial in which the group never holds an entity.
        self._last = np.zeros((n_trials, 2))

    def observe(self, state: TaskState) -> None:
        group = state.groups[self._index]
        trials = self._last.shape[0]
        present = np.broadcast_to(group.present, (trials, group.present.shape[1]))
        centres = np.broadcast_to(group.shapes("centres"), (*present.shape, 2))
        count = present.sum(axis=1)
        # Absent slots may hold NaN: they are left out, never multiplied by 0.
        total = np.where(present[..., None], centres, 0.0).sum(axis=1)
        now = np.asarray(state.active) & (count > 0)
        self._last[now] = total[now] / count[now, None]

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        return per_controller(self._last, trials)
