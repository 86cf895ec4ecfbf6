"""What the engine calls while it runs a batch: observers of the task state."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

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


@runtime_checkable
class NetworkObserver(Protocol):
    """An observer that also asks for the robots' network inputs and outputs.

    Characterisations built from what the controllers sense and do (a sensor-effector
    state count, a mean sensor-effector vector) need these; the engine hands them
    only to observers that have this method, so the others cost nothing.
    """

    def observe_network(
        self,
        trials: np.ndarray,
        inputs: np.ndarray,
        outputs: np.ndarray,
        enabled: np.ndarray,
    ) -> None:
        """Called at every step, before the physics, for the trials that run it.

        Args:
            trials: (n,) batch indices of the trials taking this step.
            inputs: (n, R, I) the network inputs of their R controlled robots.
            outputs: (n, R, O) the network outputs, in [0, 1].
            enabled: (n, R) whether each robot is still in play (not escaped,
                captured or dead).

        The arrays are the engine's own: an observer that keeps them must copy.
        """
        ...
