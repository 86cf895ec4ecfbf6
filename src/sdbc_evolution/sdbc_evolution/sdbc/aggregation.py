"""Aggregation of feature samples into a fixed-length raw characterisation: the
paper's mode and the others :class:`~.options.SdbcOptions` offers, streaming (the
trajectory is never kept).

The paper's mode, ``mean+final``: at the end of a trial of length T, each per-step
feature x_f(1..T) becomes two dimensions, and the trial length one more (section
"Aggregation of feature samples"):

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

The other modes (:func:`make_aggregator`; a feature never defined gives 0, and the
trial length is the last dimension in every mode):

- ``mean``: ``[M_1..M_F, T]``; ``final``: ``[F_1..F_F, T]`` (the authors' later code).
- ``frames: N``: the mean of each feature over N equal windows of the trial's own
  length, window k covering steps t with floor((t - 1) N / T) = k, frame-major:
  ``[frame 1: x_1..x_F, ..., frame N: x_1..x_F, T]``. Streaming keeps N x 16 bins per
  feature; their width starts at one step and doubles (neighbours merged) whenever a
  trial outgrows them. A bin goes to the window of its first step, so the result is
  exact for trials up to 16 N steps and whenever window edges fall on bin edges;
  otherwise a window edge is off by less than one bin, and a bin is narrower than
  2T / 16N = T / 8N steps (its width doubles only once the trial outgrows it).
  A window a short trial (T < N) leaves empty gets 0.
- ``regression``: the least-squares line x_f(t) ~ a_f + b_f t over the defined steps
  (t = 1..T): ``[a_1..a_F, b_1..b_F, T]``, from five running sums per feature. A
  feature defined at one step only has slope 0 and that value as intercept.

Every mode takes a step as per-feature sums and counts (F, B), the form
:class:`~.features.StepFeatures` computes; :func:`mode_names` names the
dimensions.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from sdbc_sim.compiled import compiled

from sdbc_evolution.sdbc.options import MODES

UNDEFINED_VALUE = 0.0
"""M_f and F_f of a feature never defined during a trial (docs/method.md,
"Aggregation")."""


MEAN_SUFFIX = "(M)"
"""Marks a feature's mean over the trial, as in the paper's Table 2."""
FINAL_SUFFIX = "(F)"
"""Marks a feature's final value, as in the paper's Table 2."""
LENGTH_NAME = "Simulation length"
"""The last dimension: the trial length in steps."""
BINS_PER_FRAME = 16
"""Streaming bins per window of ``frames``: the resolution of window edges."""


def mode_names(mode: str, frames: int, features: tuple[str, ...]) -> tuple[str, ...]:
    """The human name of every dimension a mode makes of ``features``."""
    if mode == "mean+final":
        body = [f"{n} {MEAN_SUFFIX}" for n in features] + [
            f"{n} {FINAL_SUFFIX}" for n in features
        ]
    elif mode == "mean":
        body = [f"{n} {MEAN_SUFFIX}" for n in features]
    elif mode == "final":
        body = [f"{n} {FINAL_SUFFIX}" for n in features]
    elif mode == "frames":
        body = [
            f"{n} (frame {k + 1}/{frames})" for k in range(frames) for n in features
        ]
    elif mode == "regression":
        body = [f"{n} (intercept)" for n in features] + [
            f"{n} (slope)" for n in features
        ]
    else:
        raise ValueError(f"unknown aggregation mode {mode!r}; known: {MODES}")
    return (*body, LENGTH_NAME)


def characterisation_length(n_features: int) -> int:
    """``2 F + 1``: a mean and a final value per feature, then the trial length."""
    return 2 * n_features + 1


class ModeAggregator(ABC):
    """Streams the steps of B trials into (B, D) vectors, one mode's way."""

    _length: np.ndarray
    """(B,) int: steps taken by each trial so far, kept by every mode."""

    @property
    def n_trials(self) -> int:
        """B."""
        return self._length.shape[0]

    @property
    def lengths(self) -> np.ndarray:
        """(B,) int: steps taken by each trial so far."""
        return self._length.copy()

    @abstractmethod
    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        """Adds one step: ``values`` (B, F), NaN where undefined, for the
        ``active`` (B,) trials; inactive trials are left as they are."""

    @abstractmethod
    def result(self) -> np.ndarray:
        """(B, D) the vectors of every trial so far."""

    def update_from_totals(
        self, total: np.ndarray, count: np.ndarray, active: np.ndarray
    ) -> None:
        """Adds one step given each feature as ``total / count``, both (F, B),
        undefined where the count is 0."""
        with np.errstate(invalid="ignore", divide="ignore"):
            values = np.where(count > 0, total / count, np.nan).T
        self.update(values, active)

    def update_trials(
        self, trials: np.ndarray, total: np.ndarray, count: np.ndarray
    ) -> None:
        """Adds one step of the ``trials`` (n,) given as ``total / count``, both
        (F, n), all of them active; the other trials are left as they are."""
        values = np.full((self.n_trials, total.shape[0]), np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            values[trials] = np.where(count > 0, total / count, np.nan).T
        active = np.zeros(self.n_trials, dtype=bool)
        active[trials] = True
        self.update(values, active)


class TrialAggregator(ModeAggregator):
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
        # Over contiguous rows, which the compiler vectorises (a third of the
        # time at 2000 trials); the extractor's rows always are.
        if not (total.flags.c_contiguous and count.flags.c_contiguous):
            total, count = np.ascontiguousarray(total), np.ascontiguousarray(count)
        _add_totals(
            total, count, active, self._sum, self._count, self._last, self._length
        )

    def update_trials(
        self, trials: np.ndarray, total: np.ndarray, count: np.ndarray
    ) -> None:
        """Adds one step of the ``trials`` (n,) given as ``total / count``, both
        (F, n), all of them active; the other trials are left as they are."""
        # One compiled pass, as update_from_totals: the extractor calls this at
        # every step once few trials are left, where numpy's calls cost more
        # than their arithmetic.
        _add_trial_totals(
            total,
            count,
            np.asarray(trials, dtype=np.int64),
            self._sum,
            self._count,
            self._last,
            self._length,
        )

    def _add(self, defined: np.ndarray, active: np.ndarray) -> None:
        # Undefined and inactive values may be anything: overwritten, never added.
        # (np.putmask is several times faster than ufuncs with where=.)
        value = self._value
        np.putmask(value, np.logical_not(defined, out=self._undefined), 0.0)
        self._sum += value
        self._count += defined
        np.putmask(self._last, defined, value)
        self._length += active

    def result(self) -> np.ndarray:
        """(B, 2F + 1): ``[means, finals, length]`` of every trial so far."""
        means = np.full_like(self._sum, UNDEFINED_VALUE)
        np.divide(self._sum, self._count, out=means, where=self._count > 0)
        return np.concatenate(
            [means.T, self._last.T, self._length[:, None].astype(np.float64)], axis=1
        )


def add_value(
    total: float,
    count: float,
    f: int,
    b: int,
    sums: np.ndarray,
    counts: np.ndarray,
    last: np.ndarray,
) -> None:
    """Adds feature ``f``'s ``total / count`` to trial ``b``'s running sums, as
    :meth:`TrialAggregator.update` does: defined where the count is > 0, an
    undefined value adding 0 (its total is 0 too: dividing by 1 keeps it) and
    leaving the last value as it was."""
    defined = count > 0.0
    # Divided whatever the count and then chosen, with no branch, so that the
    # compiler vectorises the loops over trials; an undefined quotient (of an
    # inactive trial's anything) is never kept.
    quotient = total / (count if count >= 1.0 else 1.0)
    value = quotient if defined else 0.0
    sums[f, b] += value
    counts[f, b] += 1.0 if defined else 0.0
    last[f, b] = value if defined else last[f, b]


@compiled(
    "void(float64[:, ::1], float64[:, ::1], boolean[:], float64[:, ::1], "
    "float64[:, ::1], float64[:, ::1], int64[::1])",
    calls=(add_value,),
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
            # An inactive trial's value is undefined, whatever its count.
            c = count[f, b] if active[b] else 0.0
            add_value(total[f, b], c, f, b, sums, counts, last)
    for b in range(length.shape[0]):
        if active[b]:
            length[b] += 1


@compiled(
    "void(float64[:, :], float64[:, :], int64[::1], float64[:, ::1], "
    "float64[:, ::1], float64[:, ::1], int64[::1])",
    calls=(add_value,),
)
def _add_trial_totals(
    total: np.ndarray,
    count: np.ndarray,
    trials: np.ndarray,
    sums: np.ndarray,
    counts: np.ndarray,
    last: np.ndarray,
    length: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against TrialAggregator.update
    """:func:`_add_totals` for the ``trials`` (n,) only, all of them active,
    given as ``total / count`` (F, n)."""
    for f in range(total.shape[0]):
        for j in range(trials.shape[0]):
            add_value(total[f, j], count[f, j], f, trials[j], sums, counts, last)
    for j in range(trials.shape[0]):
        length[trials[j]] += 1


class MeanFinal(ModeAggregator):
    """``mean+final``, ``mean`` or ``final``: the paper's aggregator, sliced."""

    def __init__(self, n_trials: int, n_features: int, mode: str) -> None:
        self._inner = TrialAggregator(n_trials, n_features)
        self._mode = mode
        # The same array, which the inner aggregator updates in place.
        self._length = self._inner._length

    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        self._inner.update(values, active)

    def update_from_totals(
        self, total: np.ndarray, count: np.ndarray, active: np.ndarray
    ) -> None:
        self._inner.update_from_totals(total, count, active)

    def update_trials(
        self, trials: np.ndarray, total: np.ndarray, count: np.ndarray
    ) -> None:
        self._inner.update_trials(trials, total, count)

    def result(self) -> np.ndarray:
        full = self._inner.result()
        f = self._inner.n_features
        if self._mode == "mean":
            return np.concatenate([full[:, :f], full[:, -1:]], axis=1)
        if self._mode == "final":
            return full[:, f:]
        return full


class Regression(ModeAggregator):
    """``regression``: intercept and slope of x_f(t) over the defined steps."""

    def __init__(self, n_trials: int, n_features: int) -> None:
        shape = (n_trials, n_features)
        self._n = np.zeros(shape)
        self._t = np.zeros(shape)
        self._tt = np.zeros(shape)
        self._x = np.zeros(shape)
        self._tx = np.zeros(shape)
        self._length = np.zeros(n_trials, dtype=np.int64)

    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        self._length += active
        t = self._length[:, None].astype(np.float64)
        defined = ~np.isnan(values) & active[:, None]
        x = np.where(defined, values, 0.0)
        td = np.where(defined, t, 0.0)
        self._n += defined
        self._t += td
        self._tt += td * td
        self._x += x
        self._tx += td * x

    def result(self) -> np.ndarray:
        n, st, stt, sx, stx = self._n, self._t, self._tt, self._x, self._tx
        denominator = n * stt - st * st
        fitted = denominator > 0
        slope = np.zeros_like(n)
        np.divide(n * stx - st * sx, denominator, out=slope, where=fitted)
        intercept = np.full_like(n, UNDEFINED_VALUE)
        np.divide(sx - slope * st, n, out=intercept, where=n > 0)
        return np.concatenate(
            [intercept, slope, self._length[:, None].astype(np.float64)], axis=1
        )


class Frames(ModeAggregator):
    """``frames: N``: means over N equal windows of each trial's own length."""

    def __init__(self, n_trials: int, n_features: int, frames: int) -> None:
        self.frames = frames
        self.bins = frames * BINS_PER_FRAME
        self._sum = np.zeros((n_trials, self.bins, n_features))
        self._count = np.zeros((n_trials, self.bins, n_features))
        self._length = np.zeros(n_trials, dtype=np.int64)
        # Width of every trial's bins; the running trials all share the same one.
        self._width = np.ones(n_trials, dtype=np.int64)

    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        rows = np.flatnonzero(active)
        if rows.size == 0:
            return
        step = int(self._length[rows[0]]) + 1  # running trials share their length
        width = int(self._width[rows[0]])
        if step > self.bins * width:
            # Merge neighbouring bins of the running trials: the width doubles.
            for array in (self._sum, self._count):
                merged = array[rows, 0::2] + array[rows, 1::2]
                array[rows] = 0.0
                array[rows, : self.bins // 2] = merged
            width *= 2
            self._width[rows] = width
        b = (step - 1) // width
        sample = values[rows]
        defined = ~np.isnan(sample)
        self._sum[rows, b] += np.where(defined, sample, 0.0)
        self._count[rows, b] += defined
        self._length[rows] += 1

    def result(self) -> np.ndarray:
        n_trials, _, n_features = self._sum.shape
        out = np.full((n_trials, self.frames, n_features), UNDEFINED_VALUE)
        first_step = np.arange(self.bins)[None, :] * self._width[:, None]  # 0-based
        length = np.maximum(self._length, 1)[:, None]
        window = np.minimum(first_step * self.frames // length, self.frames - 1)
        for k in range(self.frames):
            mask = (window == k)[..., None]
            total = (self._sum * mask).sum(axis=1)
            count = (self._count * mask).sum(axis=1)
            np.divide(total, count, out=out[:, k], where=count > 0)
        return np.concatenate(
            [out.reshape(n_trials, -1), self._length[:, None].astype(np.float64)],
            axis=1,
        )


def make_aggregator(
    mode: str, frames: int, n_trials: int, n_features: int
) -> ModeAggregator:
    """The streaming aggregator of a mode."""
    if mode in ("mean+final", "mean", "final"):
        return MeanFinal(n_trials, n_features, mode)
    if mode == "regression":
        return Regression(n_trials, n_features)
    if mode == "frames":
        return Frames(n_trials, n_features, frames)
    raise ValueError(f"unknown aggregation mode {mode!r}; known: {MODES}")


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
