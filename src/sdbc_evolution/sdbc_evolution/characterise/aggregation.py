"""Aggregation modes of the SDBC: how a trial's per-step feature samples become
fixed-length dimensions, streaming (the trajectory is never kept).

A feature x_f is NaN at steps where it is undefined; each mode ignores those steps and
gives 0 where a feature was never defined (the paper's rule). Every mode appends the
trial length T as the last dimension, as the paper's characterisation does.

- ``mean+final`` (the paper): ``[M_1..M_F, F_1..F_F, T]``, the mean over the trial
  and the last defined value (:class:`sdbc_evolution.sdbc.aggregation.TrialAggregator`).
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
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from sdbc_evolution.sdbc.aggregation import UNDEFINED_VALUE, TrialAggregator
from sdbc_evolution.sdbc.characterisation import FINAL_SUFFIX, LENGTH_NAME, MEAN_SUFFIX

MODES = ("mean+final", "mean", "final", "frames", "regression")
"""Aggregation modes; ``frames`` takes a window count."""
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


class ModeAggregator(ABC):
    """Streams (B, F) per-step samples of B trials into (B, D) vectors."""

    @abstractmethod
    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        """Adds one step: ``values`` (B, F), NaN where undefined, for the
        ``active`` (B,) trials."""

    @abstractmethod
    def result(self) -> np.ndarray:
        """(B, D) the vectors of every trial so far."""


class MeanFinal(ModeAggregator):
    """``mean+final``, ``mean`` or ``final``: the paper's aggregator, sliced."""

    def __init__(self, n_trials: int, n_features: int, mode: str) -> None:
        self._inner = TrialAggregator(n_trials, n_features)
        self._mode = mode

    def update(self, values: np.ndarray, active: np.ndarray) -> None:
        self._inner.update(values, active)

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
