"""What a characteriser is: an engine observer that turns a batch's trials into
per-controller behaviour vectors with named dimensions. It is a part
(:mod:`sdbc_sim.parts`): made from its options (``options_class``), registered in
:mod:`.registry` or by an entry point of the group ``sdbc.characterisations``.

A characteriser is built fresh for every batch (chunk) a worker evaluates. Those
that observe the engine are handed to ``run_batch`` as observers; those that also
need the robots' network inputs and outputs implement ``observe_network``
(:class:`sdbc_sim.observer.NetworkObserver`) and get them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np
from sdbc_sim.parts import NoOptions


class Characteriser(ABC):
    """Produces one characterisation of every controller of a batch.

    Class attributes:
        options_class: Its options (a settings class, every option defaulted).
        needs_network: It reads the robots' network inputs and outputs
            (``observe_network``), which a task-state stream does not carry.
        mean_of_trials: Its ``controller_vectors(result, T)`` is, to the bit,
            :func:`per_controller` of the vectors it gives the same trials one
            controller each (``T = 1``). Evaluators then run requests with
            different trials per controller in one batch
            (``Evaluator.evaluate_together``); a part that cannot say so is
            evaluated request by request.
    """

    options_class: ClassVar[type] = NoOptions
    needs_network: ClassVar[bool] = False
    mean_of_trials: ClassVar[bool] = False
    observes: bool = True
    """Whether ``run_batch`` should hand it the task states (and, with
    ``observe_network``, the network arrays)."""

    def __init__(self, options: Any = None) -> None:
        self.options = self.options_class() if options is None else options

    def start(self, description: Any, n_trials: int) -> None:
        """Called by the engine before a batch (an observer's first call)."""
        return None  # a characteriser that keeps no state needs no start

    def observe(self, state: Any) -> None:
        """Called by the engine after every step; by default nothing to do."""
        return None  # a characteriser of network arrays reads no task state

    @abstractmethod
    def names(self, task: Any) -> tuple[str, ...]:
        """The human name of every dimension, for ``task``.

        Raises:
            ValueError: The characterisation cannot be made for this task (the
                message names the characteriser and the problem).
        """

    @abstractmethod
    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        """(G, D) vectors of the G controllers after ``run_batch`` returned
        ``result``; ``trials`` per controller, laid out controller-major."""


def per_controller(per_trial: np.ndarray, trials: int) -> np.ndarray:
    """(G, D) mean over each controller's ``trials`` rows of (G T, D) vectors."""
    return per_trial.reshape(per_trial.shape[0] // trials, trials, -1).mean(axis=1)
