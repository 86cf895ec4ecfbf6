"""Aggregation of feature samples into a fixed-length raw characterisation.

At the end of a trial of length T, each per-step feature x_f(1..T) becomes two
dimensions, and the trial length one more (section "Aggregation of feature samples"):

- the mean over the trial ignoring undefined steps,
  ``M_f = sum_{t: x_f(t) defined} x_f(t) / |{t: x_f(t) defined}|``, 0 if never defined;
- the final value ``F_f = x_f(t*)`` with t* the last step where x_f is defined,
  0 if never defined (the authors' choice; the paper is silent);
- the trial length T.

The vector is ordered ``[M_1 .. M_F, F_1 .. F_F, T]``: length ``2 F + 1``.
:class:`TrialAggregator` does this streaming, keeping one running sum, count and last
value per feature and trial, never the trajectory; :func:`aggregate_trial` does it in
one go from stored samples, as the reference the streaming form must match. A
controller's vector is the mean over its trials (:func:`mean_over_trials`).
"""

from __future__ import annotations

import numpy as np
from sdbc_sim.compiled import compiled

UNDEFINED_VALUE = 0.0
"""M_f and F_f of a feature never defined during a trial (docs/method.md,
"Aggregation")."""


def characterisation_length(n_features: int) -> int:
    """``2 F + 1``: a mean and a final value per feature, then the trial length."""
    return 2 * n_features + 1


class TrialAggregator:
    """Streaming mean/final/length aggregation over a batch of trials.

    Its running sums, counts and last values are feature-major, (F, B), so that the
    extractor's per-step rows add without a transpose.

    Args:
        n_trials: B, the trials of the batch.
        n_features: F, the per-step features.
    """

    def __init__(self, n_trials: int, n_features: int) -> None:
        if n_trials < 0 or n_features < 0:
            raise ValueError(
                f"aggregator: n_trials {n_trials} and n_features {n_features} "
                "must be >= 0"
            )
        self._sum = np.zeros((n_features, n_trials))
        self._count = np.zeros((n_features, n_trials))
        self._last = np.full((n_features, n_trials), UNDEFINED_VALUE)
        self._length = np.zeros(n_trials, dtype=np.int64)
        self._value = np.empty((n_features, n_trials))
        self._defined = np.empty((n_features, n_trials), dtype=bool)
        self._undefined = np.empty((n_features, n_trials), dtype=bool)

    @property
    def n_trials(self) -> int:
        """B."""
        return self._sum.shape[1]

    @property
    def n_features(self) -> int:
        """F."""
        return self._sum.shape[0]

    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        """Adds one step: ``values`` (B, F), NaN where undefined, for the ``active``
        (B,) trials; inactive trials are left as they are."""
        if values.shape != (self.n_trials, self.n_features) or active.shape != (
            self.n_trials,
        ):
            raise ValueError(
                f"aggregator: values {values.shape} and active {active.shape} do not "
                f"fit {self.n_trials} trials of {self.n_features} features"
            )
        defined = np.isnan(values.T, out=self._defined)
        np.logical_not(defined, out=defined)
        defined &= active
        np.copyto(self._value, values.T)
        self._add(defined, active)

    def update_from_totals(
        self, total: np.ndarray, count: np.ndarray, active: np.ndarray
    ) -> None:
        """Adds one step given each feature as ``total / count``, both (F, B),
        undefined where the count is 0; saves :meth:`update`'s NaN round trip.
        Counts are whole numbers >= 0."""
        # One compiled pass instead of a dozen whole-array ones (the extractor
        # calls this at every step); :meth:`update` is its numpy formulation.
        _add_totals(
            total, count, active, self._sum, self._count, self._last, self._length
        )

    def update_trials(
        self, trials: np.ndarray, total: np.ndarray, count: np.ndarray
    ) -> None:
        """Adds one step of the ``trials`` (n,) given as ``total / count``, both
        (F, n), all of them active; the other trials are left as they are."""
        defined = count > 0.0
        value = np.divide(total, np.maximum(count, 1.0))
        np.putmask(value, ~defined, 0.0)
        self._sum[:, trials] += value
        self._count[:, trials] += defined
        last = self._last[:, trials]
        np.putmask(last, defined, value)
        self._last[:, trials] = last
        self._length[trials] += 1

    def _add(self, defined: np.ndarray, active: np.ndarray) -> None:
        # Undefined and inactive values may be anything: overwritten, never added.
        # (np.putmask is several times faster than ufuncs with where=.)
        value = self._value
        np.putmask(value, np.logical_not(defined, out=self._undefined), 0.0)
        self._sum += value
        self._count += defined
        np.putmask(self._last, defined, value)
        self._length += active

    @property
    def lengths(self) -> np.ndarray:
        """(B,) int: steps taken by each trial so far."""
        return self._length.copy()

    def result(self) -> np.ndarray:
        """(B, 2F + 1): ``[means, finals, length]`` of every trial so far."""
        means = np.full_like(self._sum, UNDEFINED_VALUE)
        np.divide(self._sum, self._count, out=means, where=self._count > 0)
        return np.concatenate(
            [means.T, self._last.T, self._length[:, None].astype(np.float64)], axis=1
        )


@compiled(
    "void(float64[:, :], float64[:, :], boolean[:], float64[:, ::1], "
    "float64[:, ::1], float64[:, ::1], int64[::1])"
)
def _add_totals(
    total: np.ndarray,
    count: np.ndarray,
    active: np.ndarray,
    sums: np.ndarray,
    counts: np.ndarray,
    last: np.ndarray,
    length: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against TrialAggregator.update
    """Adds one step given as ``total / count`` (F, B) for the ``active`` (B,)
    trials to the running ``sums``, ``counts``, ``last`` values (F, B) and
    ``length`` (B,), doing per value what :meth:`TrialAggregator.update` does: a
    value is defined where its count is > 0 in an active trial, an undefined one
    adds 0 (its total is 0 too: dividing by 1 keeps it) and leaves the last value
    as it was."""
    for f in range(total.shape[0]):
        for b in range(total.shape[1]):
            c = count[f, b]
            defined = c > 0.0 and active[b]
            value = total[f, b] / (c if c >= 1.0 else 1.0) if defined else 0.0
            sums[f, b] += value
            counts[f, b] += 1.0 if defined else 0.0
            if defined:
                last[f, b] = value
    for b in range(length.shape[0]):
        if active[b]:
            length[b] += 1


def aggregate_trial(samples: np.ndarray) -> np.ndarray:
    """The raw characterisation of one trial from all its samples at once.

    Args:
        samples: (T, F) feature values of every step of the trial, NaN where undefined.

    Returns:
        (2F + 1,) ``[means, finals, T]``.
    """
    samples = np.asarray(samples, dtype=np.float64)
    if samples.ndim != 2:
        raise ValueError(
            f"aggregate_trial: samples must be (T, F), got {samples.shape}"
        )
    n_steps, n_features = samples.shape
    if n_steps == 0:
        return np.concatenate([np.full(2 * n_features, UNDEFINED_VALUE), [0.0]])
    defined = ~np.isnan(samples)
    counts = defined.sum(axis=0)
    sums = np.where(defined, samples, 0.0).sum(axis=0)
    means = np.full(n_features, UNDEFINED_VALUE)
    np.divide(sums, counts, out=means, where=counts > 0)
    finals = np.full(n_features, UNDEFINED_VALUE)
    has_value = counts > 0
    last_step = n_steps - 1 - np.argmax(defined[::-1], axis=0)
    finals[has_value] = samples[last_step[has_value], np.flatnonzero(has_value)]
    return np.concatenate([means, finals, [float(n_steps)]])


def mean_over_trials(vectors: np.ndarray, trials_per_controller: int) -> np.ndarray:
    """Each controller's characterisation: the mean of its trials' vectors.

    Args:
        vectors: (B, D) per-trial vectors of a batch laid out controller-major, as the
            engine does (trial b belongs to controller ``b // trials_per_controller``).
        trials_per_controller: T, trials per controller.

    Returns:
        (B / T, D).
    """
    if (
        trials_per_controller < 1
        or vectors.ndim != 2
        or vectors.shape[0] % trials_per_controller
    ):
        raise ValueError(
            f"mean_over_trials: {vectors.shape} vectors do not split into "
            f"controllers of {trials_per_controller} trials"
        )
    n_controllers = vectors.shape[0] // trials_per_controller
    return vectors.reshape(n_controllers, trials_per_controller, -1).mean(axis=1)
