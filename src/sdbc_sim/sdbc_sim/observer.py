"""What the engine calls while it runs a batch: observers of the task state."""

from __future__ import annotations

from typing import Protocol

from sdbc_sim.task_state import TaskDescription, TaskState


class Observer(Protocol):
    """Receives the task state of a whole batch after every step.

    The engine knows nothing of what an observer computes: the SDBC extractor, a
    recorder and a renderer are all observers.
    """

    def start(self, description: TaskDescription, n_trials: int) -> None:
        """Called once before the first step of a batch of ``n_trials`` trials."""
        ...

    def observe(self, state: TaskState) -> None:
        """Called after every step with the state of every trial of the batch."""
        ...
