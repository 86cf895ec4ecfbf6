"""The task-specific characterisation (NS-TS): what the task itself reports."""

from __future__ import annotations

from typing import Any

import numpy as np
from sdbc_sim.settings import settings

from sdbc_evolution.characterise.base import Characteriser


@settings
class TaskOptions:
    """The task-specific characterisation has no options."""


class TaskCharacteriser(Characteriser):
    """The task's own characterisation, each value in [0, 1], mean over trials."""

    options_class = TaskOptions
    mean_of_trials = True
    observes = False

    def __init__(self, options: TaskOptions | None = None) -> None:
        self.options = options or TaskOptions()

    def names(self, task: Any) -> tuple[str, ...]:
        return tuple(task.characterisation_names)

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        return np.asarray(result.controller_characterisation, dtype=np.float64)
