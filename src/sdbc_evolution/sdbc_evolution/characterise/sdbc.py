"""The SDBC as a characteriser: the one extractor
(:class:`~sdbc_evolution.sdbc.characterisation.SdbcExtractor`) with the
declaration's :class:`~sdbc_evolution.sdbc.options.SdbcOptions` (the paper's by
default), its dimensions named by
:func:`~sdbc_evolution.sdbc.characterisation.dimension_names`.

``OptionedSdbcExtractor`` and ``sdbc_dimension_names`` are the names these had when
the options had an extractor of their own; they stay for code that imports them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sdbc_sim.task_state import TaskDescription, TaskState

from sdbc_evolution.characterise.base import Characteriser, per_controller
from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names
from sdbc_evolution.sdbc.options import SdbcOptions

__all__ = [
    "OptionedSdbcExtractor",
    "SdbcCharacteriser",
    "SdbcOptions",
    "sdbc_dimension_names",
]

sdbc_dimension_names = dimension_names
"""The former name of :func:`dimension_names`."""


class OptionedSdbcExtractor(SdbcExtractor):
    """The SDBC extractor with ``options`` and no value checks, as the former
    extractor of options was; prefer ``SdbcExtractor(options, ...)``."""

    def __init__(
        self, options: SdbcOptions, fixed_static_geometry: bool = True
    ) -> None:
        super().__init__(
            options, check_values=False, fixed_static_geometry=fixed_static_geometry
        )


class SdbcCharacteriser(Characteriser):
    """The SDBC of every controller: the mean over its trials of the trial vectors."""

    options_class = SdbcOptions
    mean_of_trials = True

    def __init__(self, options: SdbcOptions | None = None) -> None:
        self.options = options or SdbcOptions()
        # Runs check nothing per step: the engine's tasks are checked by the
        # conformance tests, and a check costs a few reductions every step.
        self.extractor = SdbcExtractor(self.options, check_values=False)

    def names(self, task: Any) -> tuple[str, ...]:
        return dimension_names(task.description, self.options)

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.extractor.start(description, n_trials)

    def observe(self, state: TaskState) -> None:
        self.extractor.observe(state)

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        return per_controller(self.extractor.characterisations(), trials)
