"""The SDBC extractor: an engine observer that turns task states into raw
characterisations (steps 1 to 3 of the paper's workflow).

Each step, :class:`StepFeatures` computes the behaviour features of every trial of the
batch (eqs. 2 to 5) and a :class:`TrialAggregator` folds them into running sums,
counts and last values. At the end, every trial has a raw characterisation of length
``2 F + 1``, ``[means, finals, length]``, whose dimensions are named by
:func:`dimension_names`: "Agent group size (M)", ..., "Gate is closing (F)", ...,
"Simulation length".
"""

from __future__ import annotations

import numpy as np
from sdbc_sim.task_state import TaskDescription, TaskState, validate_task_state

from sdbc_evolution.sdbc.aggregation import TrialAggregator
from sdbc_evolution.sdbc.features import StepFeatures, behaviour_features

MEAN_SUFFIX = "(M)"
"""Marks a feature's mean over the trial, as in the paper's Table 2."""
FINAL_SUFFIX = "(F)"
"""Marks a feature's final value, as in the paper's Table 2."""
LENGTH_NAME = "Simulation length"
"""The last dimension: the trial length in steps."""


def dimension_names(description: TaskDescription) -> tuple[str, ...]:
    """The human name of every dimension of a task's raw characterisation, in order."""
    names = [f.name for f in behaviour_features(description)]
    return (
        *(f"{n} {MEAN_SUFFIX}" for n in names),
        *(f"{n} {FINAL_SUFFIX}" for n in names),
        LENGTH_NAME,
    )


class SdbcExtractor:
    """Streams the task states of a batch into per-trial raw SDBC vectors.

    It is an engine observer (:class:`sdbc_sim.observer.Observer`): the engine calls
    :meth:`start` once per batch and :meth:`observe` after every step; then
    :meth:`characterisations` gives the (B, D) raw vectors. It keeps O(B F) numbers,
    never the trajectory, and can be reused for the next batch. The shapes of static
    groups are read at a batch's first step only (static entities never move), unless
    ``fixed_static_geometry`` is off.

    The engine keeps stepping a batch until its last trial ends; once few trials
    are left, only those are computed (gathered into a smaller batch), so the cost
    of a step follows the trials that take it, as the engine's does.

    Args:
        check_values: Check, every step, that no present entity of an active trial
            has a NaN or infinite attribute or coordinate, and that every group's
            size is within its limits; off saves a few numpy reductions per step.
        compact_below: Compute only the active trials once they are at most this
            fraction of the batch (0 never, 1 always). Gathering them costs about
            what it saves at a quarter of the batch (measured at 2000 trials on the
            three tasks); at 5% it halves a step's cost.
        fixed_static_geometry: Read static groups' shapes at the first step only
            and reuse them slot by slot. True for the engine, whose slots keep their
            entity; off for task states whose slots do not (a message packs the
            entities present into its first slots, so a static group whose
            membership changes moves its entities between slots).
    """

    def __init__(
        self,
        check_values: bool = True,
        compact_below: float = 0.25,
        fixed_static_geometry: bool = True,
    ) -> None:
        if not 0.0 <= compact_below <= 1.0:
            raise ValueError(
                f"SDBC extractor: compact_below {compact_below} must be in [0, 1]"
            )
        self.check_values = check_values
        self.compact_below = compact_below
        self.fixed_static_geometry = fixed_static_geometry
        self._features: StepFeatures | None = None
        self._aggregator: TrialAggregator | None = None
        self._step = 0
        # Set by start(); observe() and the results refuse to run before it.
        self._previous_active = np.zeros(0, dtype=bool)

    def start(self, description: TaskDescription, n_trials: int) -> None:
        """Prepares for a batch of ``n_trials`` trials of the described task."""
        if n_trials < 1:
            raise ValueError(f"SDBC extractor: n_trials {n_trials} < 1")
        self._features = StepFeatures(
            description, fixed_static_geometry=self.fixed_static_geometry
        )
        self._aggregator = TrialAggregator(n_trials, self._features.n_features)
        self._step = 0
        self._previous_active = np.ones(n_trials, dtype=bool)

    def redescribe(self, description: TaskDescription) -> None:
        """Continues the batch under ``description``, which must have the same
        features as the current one (it may differ in a group's geometry, learnt
        when the group's first entity appears); the sums so far are kept.

        Raises:
            ValueError: If the features differ.
        """
        features = self._started()
        if behaviour_features(description) != features.features:
            raise ValueError(
                f"SDBC extractor, task {description.name!r}: a new description must "
                "keep the features of the old one"
            )
        self._features = StepFeatures(
            description, fixed_static_geometry=self.fixed_static_geometry
        )

    @property
    def description(self) -> TaskDescription:
        """The task description of the current batch."""
        return self._started().description

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """Names of the D dimensions of :meth:`characterisations`."""
        return dimension_names(self.description)

    def _started(self) -> StepFeatures:
        if self._features is None:
            raise RuntimeError("SDBC extractor: start() was not called")
        return self._features

    def _aggregating(self) -> TrialAggregator:
        if self._aggregator is None:
            raise RuntimeError("SDBC extractor: start() was not called")
        return self._aggregator

    def observe(self, state: TaskState) -> None:
        """Adds the step ``state.step`` of every active trial."""
        features = self._started()
        aggregator = self._aggregating()
        description = features.description
        n_trials = aggregator.n_trials
        validate_task_state(description, state, n_trials)
        if state.step != self._step + 1:
            raise ValueError(
                f"SDBC extractor, task {description.name!r}: step {state.step} follows "
                f"step {self._step}; steps must arrive in order from 1"
            )
        active = state.active
        resumed = active & ~self._previous_active
        if resumed.any():
            raise ValueError(
                f"SDBC extractor, task {description.name!r}, step {state.step}: trial "
                f"{int(np.flatnonzero(resumed)[0])} is active again after it ended"
            )
        n_active = int(np.count_nonzero(active))
        if n_active > self.compact_below * n_trials:
            total, count = features.compute(state)
            if self.check_values:
                self._check(state, total)
            aggregator.update_from_totals(total, count, active)
        elif n_active > 0:
            trials = np.flatnonzero(active)
            total, count = features.compute(state, self._padded(trials))
            total, count = total[:, :n_active], count[:, :n_active]
            if self.check_values:
                self._check(state, total, trials)
            aggregator.update_trials(trials, total, count)
        self._step = state.step
        self._previous_active = active.copy()

    def _padded(self, trials: np.ndarray) -> np.ndarray:
        """``trials`` padded by repeating the first to the next of a few sizes
        (B/2, B/4, ...), so that the scratch arrays come in a few shapes only."""
        size = self._aggregating().n_trials
        while size // 2 >= trials.shape[0]:
            size //= 2
        padded = np.full(size, trials[0])
        padded[: trials.shape[0]] = trials
        return padded

    def _check(
        self, state: TaskState, total: np.ndarray, trials: np.ndarray | None = None
    ) -> None:
        """``total`` covers the batch, or only ``trials`` (all active)."""
        features = self._started()
        description = features.description
        active = state.active
        bad = (
            ~np.isfinite(total) if trials is not None else ~np.isfinite(total) & active
        )
        if bad.any():
            f, column = np.argwhere(bad)[0]
            trial = column if trials is None else trials[column]
            raise ValueError(
                f"SDBC extractor, task {description.name!r}, step {state.step}, trial "
                f"{trial}: feature {features.features[f].name!r} is not "
                "finite; a present entity has a NaN or infinite attribute or coordinate"
            )
        for spec, group in zip(description.groups, state.groups, strict=True):
            if spec.min_size in (0, spec.max_size):
                # S = max_size slots, so only a lower limit can be broken, and
                # StepFeatures checks full groups (min_size = max_size) itself.
                continue
            size = np.broadcast_to(
                np.count_nonzero(group.present, axis=1), active.shape
            )
            out = (size < spec.min_size) & active
            if out.any():
                trial = int(np.flatnonzero(out)[0])
                raise ValueError(
                    f"SDBC extractor, task {description.name!r}, step {state.step}, "
                    f"trial {trial}: group {spec.name!r} holds {int(size[trial])} "
                    f"entities, outside its limits [{spec.min_size}, {spec.max_size}]"
                )

    @property
    def lengths(self) -> np.ndarray:
        """(B,) int: steps taken by each trial so far."""
        return self._aggregating().lengths

    def characterisations(self) -> np.ndarray:
        """(B, D) raw characterisations ``[means, finals, length]`` so far."""
        return self._aggregating().result()
