"""The SDBC extractor: an engine observer that turns task states into raw
characterisations (steps 1 to 3 of the paper's workflow), with the paper's
configuration by default and any :class:`~.options.SdbcOptions`.

Each step, :class:`StepFeatures` computes the behaviour features of every trial of the
batch (eqs. 2 to 5, and those the options add) as sums and counts, and the options'
aggregator (:mod:`.aggregation`; the paper's :class:`TrialAggregator` by default)
folds them into running sums. With the paper's options every trial has a raw
characterisation of length ``2 F + 1``, ``[means, finals, length]``, whose
dimensions are named by :func:`dimension_names`: "Agent group size (M)", ...,
"Gate is closing (F)", ..., "Simulation length".
"""

from __future__ import annotations

import numpy as np
from sdbc_sim.compiled import compiled
from sdbc_sim.task_state import (
    TaskDescription,
    TaskState,
    TaskStateCheck,
)

from sdbc_evolution.sdbc.aggregation import (
    FINAL_SUFFIX,
    LENGTH_NAME,
    MEAN_SUFFIX,
    ModeAggregator,
    make_aggregator,
    mode_names,
)
from sdbc_evolution.sdbc.features import StepFeatures, behaviour_features
from sdbc_evolution.sdbc.options import PAPER, SdbcOptions

__all__ = [
    "FINAL_SUFFIX",
    "LENGTH_NAME",
    "MEAN_SUFFIX",
    "SdbcExtractor",
    "dimension_names",
]


def dimension_names(
    description: TaskDescription, options: SdbcOptions | None = None
) -> tuple[str, ...]:
    """The human name of every dimension of a task's raw characterisation, in
    order, with ``options`` (the paper's by default).

    Raises:
        ValueError: If the options do not fit the task (naming the option).
    """
    options = options or PAPER
    names = tuple(f.name for f in behaviour_features(description, options))
    return mode_names(options.mode, options.frames, names)


class SdbcExtractor:
    """Streams the task states of a batch into per-trial raw SDBC vectors.

    The one SDBC extractor: the paper's configuration by default, any
    :class:`SdbcOptions` otherwise; every option streams (per trial it keeps the
    mode's running sums, never the trajectory) and runs the same compiled loops.
    It is an engine observer (:class:`sdbc_sim.observer.Observer`): the engine calls
    :meth:`start` once per batch and :meth:`observe` after every step; then
    :meth:`characterisations` gives the (B, D) raw vectors. It keeps O(B F) numbers,
    never the trajectory, and can be reused for the next batch. The shapes of a
    static group's slot are read at the first step the slot is present and reused
    after (static entities never move), unless ``fixed_static_geometry`` is off.

    Attributes and shapes of any real dtype (float32, integers, bool) are taken
    and converted to float64 once per step on entry
    (:func:`sdbc_sim.task_state.real_task_state`); other dtypes are refused with
    the rule in the message.

    The engine keeps stepping a batch until its last trial ends; once few trials
    are left, only those are computed (gathered into a smaller batch), so the cost
    of a step follows the trials that take it, as the engine's does.

    Args:
        options: How the SDBC is made (the paper's by default).
        check_values: Check, every step, that no present entity of an active trial
            has a NaN or infinite attribute or coordinate, and that every group's
            size is within its limits; off saves a few numpy reductions per step.
        compact_below: Compute only the active trials once they are at most this
            fraction of the batch (0 never, 1 always). Gathering them costs about
            what it saves at a quarter of the batch (measured at 2000 trials on the
            three tasks); at 5% it halves a step's cost.
        fixed_static_geometry: Read a static group's shapes slot by slot at the
            first step each slot is present and reuse them. True for the engine,
            whose slots keep their entity; off for task states whose slots do not
            (a message packs the entities present into its first slots, so a
            static group whose membership changes moves its entities between
            slots).
    """

    def __init__(
        self,
        options: SdbcOptions | None = None,
        check_values: bool = True,
        compact_below: float = 0.25,
        fixed_static_geometry: bool = True,
    ) -> None:
        if not 0.0 <= compact_below <= 1.0:
            raise ValueError(
                f"SDBC extractor: compact_below {compact_below} must be in [0, 1]"
            )
        if isinstance(options, bool):
            # The first positional argument used to be check_values.
            raise TypeError(
                "SDBC extractor: options must be SdbcOptions or None; pass "
                "check_values by keyword"
            )
        self.options = options or PAPER
        self.check_values = check_values
        self.compact_below = compact_below
        self.fixed_static_geometry = fixed_static_geometry
        self._features: StepFeatures | None = None
        self._aggregator: ModeAggregator | None = None
        self._check_state: TaskStateCheck | None = None
        self._limited: tuple[int, ...] = ()
        self._step = 0
        # Set by start(); observe() and the results refuse to run before it.
        self._previous_active = np.zeros(0, dtype=bool)

    def start(self, description: TaskDescription, n_trials: int) -> None:
        """Prepares for a batch of ``n_trials`` trials of the described task."""
        if n_trials < 1:
            raise ValueError(f"SDBC extractor: n_trials {n_trials} < 1")
        self._features = self._step_features(description)
        options = self.options
        self._aggregator = make_aggregator(
            options.mode, options.frames, n_trials, self._features.n_features
        )
        self._check_state = TaskStateCheck(description, n_trials)
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
        if behaviour_features(description, self.options) != features.features:
            raise ValueError(
                f"SDBC extractor, task {description.name!r}: a new description must "
                "keep the features of the old one"
            )
        self._features = self._step_features(description)
        self._check_state = TaskStateCheck(description, self._aggregating().n_trials)

    def _step_features(self, description: TaskDescription) -> StepFeatures:
        # Groups whose size the values check bounds: at most max_size slots
        # leave only a lower limit to break, and StepFeatures checks full
        # groups (min_size = max_size) itself.
        self._limited = tuple(
            g
            for g, spec in enumerate(description.groups)
            if spec.min_size not in (0, spec.max_size)
        )
        return StepFeatures(
            description,
            fixed_static_geometry=self.fixed_static_geometry,
            options=self.options,
        )

    @property
    def description(self) -> TaskDescription:
        """The task description of the current batch."""
        return self._started().description

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """Names of the D dimensions of :meth:`characterisations`."""
        return dimension_names(self.description, self.options)

    def _started(self) -> StepFeatures:
        if self._features is None:
            raise RuntimeError("SDBC extractor: start() was not called")
        return self._features

    def _aggregating(self) -> ModeAggregator:
        if self._aggregator is None:
            raise RuntimeError("SDBC extractor: start() was not called")
        return self._aggregator

    def observe(self, state: TaskState) -> None:
        """Adds the step ``state.step`` of every active trial."""
        features = self._started()
        aggregator = self._aggregating()
        check_state = self._check_state
        assert check_state is not None  # set with the aggregator
        state = check_state(state)
        if state.step != self._step + 1:
            raise ValueError(
                f"SDBC extractor, task {features.description.name!r}: step "
                f"{state.step} follows step {self._step}; steps must arrive in "
                "order from 1"
            )
        active = state.active
        n_trials = aggregator.n_trials
        n_active = _count_active(active, self._previous_active)
        if n_active < 0:
            raise ValueError(
                f"SDBC extractor, task {features.description.name!r}, step "
                f"{state.step}: trial {-1 - n_active} is active again after it ended"
            )
        if n_active > self.compact_below * n_trials:
            total, count = features.compute(state, layout=check_state.layout)
            if self.check_values:
                self._check(state, total)
            aggregator.update_from_totals(total, count, active)
        elif n_active > 0:
            trials = np.flatnonzero(active)
            padded, count = features.compute(state, self._padded(trials))
            if self.check_values:
                self._check(state, padded, trials)
            aggregator.update_trials(trials, padded[:, :n_active], count[:, :n_active])
        self._step = state.step
        np.copyto(self._previous_active, active)

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
        """``total`` covers the batch, or only ``trials`` (all active) in its
        first columns."""
        features = self._started()
        description = features.description
        active = state.active
        n = active.shape[0] if trials is None else trials.shape[0]
        first = _first_not_finite(total, active, n, trials is not None)
        if first >= 0:
            f, column = divmod(first, n)
            trial = column if trials is None else trials[column]
            raise ValueError(
                f"SDBC extractor, task {description.name!r}, step {state.step}, trial "
                f"{trial}: feature {features.features[f].name!r} is not "
                "finite; a present entity has a NaN or infinite attribute or coordinate"
            )
        for g in self._limited:
            spec, group = description.groups[g], state.groups[g]
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
        """(B, D) raw characterisations so far (the paper's: ``[means, finals,
        length]``)."""
        return self._aggregating().result()


@compiled("int64(boolean[:], boolean[::1])")
def _count_active(
    active: np.ndarray, previous: np.ndarray
) -> int:  # pragma: no cover - compiled; tested through SdbcExtractor
    """The number of ``active`` trials, or ``-1 - b`` for the first trial ``b``
    active again after it ended (inactive in ``previous``)."""
    # Without a branch, which the compiler vectorises; the search only if due.
    n = 0
    resumed = False
    for b in range(active.shape[0]):
        n += active[b]
        resumed |= active[b] and not previous[b]
    if resumed:
        for b in range(active.shape[0]):
            if active[b] and not previous[b]:
                return -1 - b
    return n


@compiled("int64(float64[:, ::1], boolean[:], int64, boolean)")
def _first_not_finite(
    total: np.ndarray, active: np.ndarray, n: int, all_active: bool
) -> int:  # pragma: no cover - compiled; tested through SdbcExtractor
    """The row-major index in ``total[:, :n]`` of its first value that is NaN or
    infinite in an active trial (every column, with ``all_active``); -1 if none."""
    for f in range(total.shape[0]):
        row = total[f]
        # x - x is 0 but for NaN and infinities: a scan without a branch, which
        # the compiler vectorises, then the search only in a row that has one.
        bad = False
        for b in range(n):
            x = row[b]
            bad |= x - x != 0.0
        if bad:
            for b in range(n):
                x = row[b]
                if x - x != 0.0 and (all_active or active[b]):
                    return f * n + b
    return -1
