"""Generic characterisations from what the robots sense and do (the paper's related
work), computed from the engine's network inputs and outputs, with no task code.

- ``state_count`` (Gomes & Christensen, GECCO 2013, "sensor-effector state count"):
  at every step each robot still in play is in a state, its sensor values
  (network inputs, in [-1, 1]) and effector values (network outputs, in [0, 1])
  each discretised into ``levels`` equal bins; the team's vector counts how often
  each state was visited over the trial, divided by the number of visits (so it sums
  to 1). With more than ``max_states`` possible states, states are hashed into
  ``max_states`` buckets (a fixed multiplicative hash, the same in every process).
- ``sensor_effector_mean``: the mean over the trial's steps and the robots in play of
  every sensor and effector value.

A controller's vector is the mean over its trials, as for every characterisation.
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from sdbc_sim.limits import STATE_COUNT_STATES
from sdbc_sim.settings import Field, settings
from sdbc_sim.task_state import TaskDescription, TaskState

from sdbc_evolution.characterise.base import Characteriser, per_controller

SENSOR_RANGE = (-1.0, 1.0)
"""Range of the network inputs (every task's sensors are normalised to it)."""
EFFECTOR_RANGE = (0.0, 1.0)
"""Range of the network outputs (sigmoids)."""
_HASH_SEED = 2013
"""Seeds the multipliers of the state hash (fixed: a state's bucket must be the same
in every run and process)."""


@settings
class StateCountOptions:
    """Discretisation of the sensor-effector state count."""

    levels: Annotated[int, Field(ge=2)] = 2
    """Bins per sensor and effector value (the GECCO 2013 paper: 2)."""
    max_states: Annotated[int, Field(ge=2, le=STATE_COUNT_STATES)] = 1024
    """Most dimensions; more possible states are hashed into this many buckets
    (at most ``sdbc_sim.limits.STATE_COUNT_STATES``: the counts are trials x
    states floats)."""


@settings
class SensorEffectorMeanOptions:
    """The mean sensor-effector vector has no options."""


def _sizes(task: Any) -> tuple[int, int]:
    return int(task.network.n_inputs), int(task.network.n_outputs)


def discretise(values: np.ndarray, low: float, high: float, levels: int) -> np.ndarray:
    """Equal-width bin index in [0, levels) of each value of [low, high]."""
    scaled = np.floor((values - low) / (high - low) * levels).astype(np.int64)
    return np.clip(scaled, 0, levels - 1)


class StateCount(Characteriser):
    """Sensor-effector state count (Gomes & Christensen 2013)."""

    options_class = StateCountOptions
    needs_network = True
    mean_of_trials = True

    def __init__(self, options: StateCountOptions | None = None) -> None:
        self.options = options or StateCountOptions()
        self._counts: np.ndarray | None = None

    def _exact(self, n_values: int) -> bool:
        """Every state has a dimension of its own (Python ints: no overflow)."""
        return self.options.levels**n_values <= self.options.max_states

    def _states(self, n_values: int) -> int:
        return (
            self.options.levels**n_values
            if self._exact(n_values)
            else self.options.max_states
        )

    def names(self, task: Any) -> tuple[str, ...]:
        n_values = sum(_sizes(task))
        label = "State" if self._exact(n_values) else "State bucket"
        return tuple(f"{label} {s}" for s in range(self._states(n_values)))

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self._n_trials = n_trials
        self._counts = None

    def observe(self, state: TaskState) -> None:
        """Task states carry nothing this characterisation needs."""

    def observe_network(
        self,
        trials: np.ndarray,
        inputs: np.ndarray,
        outputs: np.ndarray,
        enabled: np.ndarray,
    ) -> None:
        """Counts, per trial, the step's discretised sensor-effector state of every
        enabled robot (see
        :meth:`sdbc_sim.observer.NetworkObserver.observe_network`)."""
        levels = self.options.levels
        codes = np.concatenate(
            [
                discretise(inputs, *SENSOR_RANGE, levels),
                discretise(outputs, *EFFECTOR_RANGE, levels),
            ],
            axis=2,
        )  # (n, R, V)
        n_values = codes.shape[2]
        states = self._states(n_values)
        if self._counts is None:
            self._counts = np.zeros((self._n_trials, states))
        if self._exact(n_values):
            index = codes @ (levels ** np.arange(n_values, dtype=np.int64))
        else:
            multipliers = np.random.default_rng(_HASH_SEED).integers(
                1, 2**31, n_values, dtype=np.int64
            )
            index = (codes @ multipliers) % states
        rows = np.repeat(trials, enabled.shape[1])[enabled.reshape(-1)]
        np.add.at(self._counts, (rows, index.reshape(-1)[enabled.reshape(-1)]), 1.0)

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        if self._counts is None:
            raise RuntimeError("state_count: no step was observed")
        totals = self._counts.sum(axis=1, keepdims=True)
        shares = np.divide(
            self._counts, totals, out=np.zeros_like(self._counts), where=totals > 0
        )
        return per_controller(shares, trials)


class SensorEffectorMean(Characteriser):
    """Mean sensor and effector values over the trial's steps and robots."""

    options_class = SensorEffectorMeanOptions
    needs_network = True
    mean_of_trials = True

    def __init__(self, options: SensorEffectorMeanOptions | None = None) -> None:
        self.options = options or SensorEffectorMeanOptions()
        self._sum: np.ndarray | None = None

    def names(self, task: Any) -> tuple[str, ...]:
        n_inputs, n_outputs = _sizes(task)
        return (
            *(f"Sensor {i + 1} (mean)" for i in range(n_inputs)),
            *(f"Effector {k + 1} (mean)" for k in range(n_outputs)),
        )

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self._n_trials = n_trials
        self._sum = None
        self._count = np.zeros(n_trials)

    def observe(self, state: TaskState) -> None:
        """Task states carry nothing this characterisation needs."""

    def observe_network(
        self,
        trials: np.ndarray,
        inputs: np.ndarray,
        outputs: np.ndarray,
        enabled: np.ndarray,
    ) -> None:
        """Adds the step's sensor and effector values of every enabled robot to its
        trial's sums (see :meth:`sdbc_sim.observer.NetworkObserver.observe_network`)."""
        values = np.concatenate([inputs, outputs], axis=2)  # (n, R, V)
        if self._sum is None:
            self._sum = np.zeros((self._n_trials, values.shape[2]))
        self._sum[trials] += np.where(enabled[..., None], values, 0.0).sum(axis=1)
        self._count[trials] += enabled.sum(axis=1)

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        if self._sum is None:
            raise RuntimeError("sensor_effector_mean: no step was observed")
        means = np.divide(
            self._sum,
            self._count[:, None],
            out=np.zeros_like(self._sum),
            where=self._count[:, None] > 0,
        )
        return per_controller(means, trials)
