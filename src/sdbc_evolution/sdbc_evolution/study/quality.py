"""Quality of the solutions: best-fitness curves, each run's best, Mann-Whitney U.

The paper's figure 2 and its significance tests, from the run directories:

- the **curve** of a run is the fitness of each generation's best individual
  re-evaluated in fresh trials (``reevaluated_fitness``; without re-evaluation,
  ``best_fitness``, which the selection of the best biases upwards); a treatment's
  curve is the mean over its runs, with the standard error of that mean as a band;
- the **best** of a run is its champion's fitness re-evaluated in many trials no
  run used (the best of the generation at its curve's highest point, see
  :mod:`.champions`) where the study re-evaluated champions; in a study that did
  not (the earlier digests), the highest value of its curve, a maximum over
  noisy few-trial estimates, biased upwards. :func:`run_statistic` says which;
  the **last** of a run is its last generation's best, re-evaluated the same way
  (or the curve's last value);
- **Mann-Whitney U** (two-sided, ``scipy.stats.mannwhitneyu``) compares the bests of
  every pair of treatments on a task. Besides U and p, the table gives Vargha and
  Delaney's A = U / (n_a n_b), the chance that a run of treatment a beats one of b
  (ties count half): 0.5 is no difference; with its 95 % bootstrap interval
  (:func:`effect_interval`: BCa, :data:`BOOTSTRAP_RESAMPLES` resamples of each
  treatment's runs apart, seeded by the task's and treatments' names so that a
  report is the same bytes every time; percentile where BCa is undefined);
- **Holm's correction** (:func:`holm`) over a family of tests: the adjusted p of
  the k-th smallest of m raw p-values is max over j <= k of (m - j + 1) p_(j),
  capped at 1. A task's fitness tests (every pair of its treatments) are one
  family, its exploration tests another (:mod:`.claims`).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import warnings
import zlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import bootstrap, mannwhitneyu

from sdbc_evolution.study.digest import RunDigest, TaskDigest


def run_best(run: RunDigest) -> float:
    """The run's champion re-evaluated, or else the highest value of its curve."""
    if run.champions is not None:
        return run.champions.fitness
    return float(np.nanmax(run.curve))


def run_last(run: RunDigest) -> float:
    """The run's last best re-evaluated, or else the last value of its curve."""
    if run.champions is not None:
        return run.champions.last_fitness
    return float(run.curve[-1])


def run_statistic(run: RunDigest) -> str:
    """Which statistic :func:`run_best` takes of the run, in words."""
    if run.champions is not None:
        return (
            f"champion re-evaluated in {run.champions.trials} fresh trials "
            f"(fitness, {run.config.evaluation.fitness_mean} mean)"
        )
    trials = run.config.evaluation.reevaluation_trials
    if run.curve_source == "reevaluated_fitness":
        return (
            f"highest point of the curve (each generation's best re-evaluated in "
            f"{trials} trials; no champion re-evaluation in this digest)"
        )
    return (
        "highest point of the curve (best fitness as selection saw it; no "
        "re-evaluation in this digest)"
    )


def task_statistic(task: TaskDigest) -> str:
    """The statistics :func:`run_best` takes of the task's runs ('; ' between
    several, which a study of one preset never has)."""
    return "; ".join(dict.fromkeys(run_statistic(r) for r in task.runs))


@dataclass(frozen=True)
class Curves:
    """Best-fitness curves of the treatments on one task.

    Attributes:
        task: Task name.
        treatments: Treatments, in the order of the arrays' first axis.
        mean: (K, G) mean over runs of each generation's curve value.
        sd: (K, G) standard deviation over runs (ddof 1; NaN with one run).
        n: (K, G) runs that reached each generation.
        sources: Curve column of each treatment's runs (see
            :func:`sdbc_evolution.study.reduce.curve_column`).
    """

    task: str
    treatments: tuple[str, ...]
    mean: np.ndarray
    sd: np.ndarray
    n: np.ndarray
    sources: tuple[str, ...]

    @property
    def se(self) -> np.ndarray:
        """Standard error of the mean, sd / sqrt(n)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sd / np.sqrt(self.n)

    @property
    def generations(self) -> np.ndarray:
        """(G,) the generation indices of the curves."""
        return np.arange(self.mean.shape[1])


def best_curves(task: TaskDigest) -> Curves:
    """Mean curve per treatment; runs of unequal length count where they reach."""
    treatments = tuple(task.treatments())
    length = max(r.generations for r in task.runs)
    k = len(treatments)
    mean = np.full((k, length), np.nan)
    sd = np.full((k, length), np.nan)
    n = np.zeros((k, length), dtype=np.int64)
    sources = []
    for i, treatment in enumerate(treatments):
        runs = task.of(treatment)
        values = np.full((len(runs), length), np.nan)
        for j, run in enumerate(runs):
            values[j, : run.generations] = run.curve
        n[i] = np.isfinite(values).sum(axis=0)
        with warnings.catch_warnings():
            # A generation no run reached is NaN, as it should be.
            warnings.simplefilter("ignore", RuntimeWarning)
            mean[i] = np.nanmean(values, axis=0)
            sd[i] = np.where(n[i] > 1, np.nanstd(values, axis=0, ddof=1), np.nan)
        sources.append("/".join(sorted({r.curve_source for r in runs})))
    return Curves(task.task, treatments, mean, sd, n, tuple(sources))


def run_bests(task: TaskDigest) -> dict[str, np.ndarray]:
    """Each run's best, per treatment (run order as found)."""
    return {t: np.array([run_best(r) for r in task.of(t)]) for t in task.treatments()}


def run_lasts(task: TaskDigest) -> dict[str, np.ndarray]:
    """Each run's last best, per treatment (run order as found)."""
    return {t: np.array([run_last(r) for r in task.of(t)]) for t in task.treatments()}


@dataclass(frozen=True)
class PairTest:
    """A two-sided Mann-Whitney U test between the bests of two treatments.

    Attributes:
        task: Task name.
        a: First treatment.
        b: Second treatment.
        n_a: Runs of a.
        n_b: Runs of b.
        median_a: Median best of a.
        median_b: Median best of b.
        mean_a: Mean best of a.
        mean_b: Mean best of b.
        u: U statistic of a.
        p: Two-sided p-value.
        effect_low: Lower end of A's 95 % bootstrap interval.
        effect_high: Upper end of it.
        p_holm: The p-value Holm-adjusted within its family (None: the test
            was made alone, no family given; verdicts then use ``p``).
    """

    task: str
    a: str
    b: str
    n_a: int
    n_b: int
    median_a: float
    median_b: float
    mean_a: float
    mean_b: float
    u: float
    p: float
    effect_low: float = math.nan
    effect_high: float = math.nan
    p_holm: float | None = None

    @property
    def effect(self) -> float:
        """A = U / (n_a n_b): the chance a run of a beats one of b."""
        return self.u / (self.n_a * self.n_b)

    @property
    def adjusted_p(self) -> float:
        """The p-value verdicts use: Holm's where the test is in a family."""
        return self.p if self.p_holm is None else self.p_holm

    def turned(self) -> PairTest:
        """The same test read as b against a."""
        return PairTest(
            self.task,
            self.b,
            self.a,
            self.n_b,
            self.n_a,
            self.median_b,
            self.median_a,
            self.mean_b,
            self.mean_a,
            self.n_a * self.n_b - self.u,
            self.p,
            1.0 - self.effect_high,
            1.0 - self.effect_low,
            self.p_holm,
        )


BOOTSTRAP_RESAMPLES = 4000
"""Resamples of A's bootstrap interval."""
CONFIDENCE = 0.95
"""Level of A's interval."""


def vargha_delaney(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    """A of ``x`` against ``y`` along ``axis`` (ties count half), vectorised for
    ``scipy.stats.bootstrap``."""
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, -1)
    y = np.moveaxis(np.asarray(y, dtype=np.float64), axis, -1)
    greater = (x[..., :, None] > y[..., None, :]).mean(axis=(-2, -1))
    ties = (x[..., :, None] == y[..., None, :]).mean(axis=(-2, -1))
    return np.asarray(greater + 0.5 * ties)


def effect_interval(
    x: np.ndarray, y: np.ndarray, seed: Sequence[int]
) -> tuple[float, float]:
    """A's 95 % bootstrap interval (see the module docstring); ``seed`` words
    seed it. With one run a side there is no interval: (0, 1)."""
    if x.size < 2 or y.size < 2:
        return 0.0, 1.0
    rng = np.random.default_rng(np.random.SeedSequence(list(seed)))
    with warnings.catch_warnings():
        # BCa is undefined when every resample gives one value (e.g. A = 1
        # throughout): the percentile interval then says what the data say.
        warnings.simplefilter("ignore")
        result = bootstrap(
            (x, y),
            vargha_delaney,
            n_resamples=BOOTSTRAP_RESAMPLES,
            confidence_level=CONFIDENCE,
            method="BCa",
            vectorized=True,
            random_state=rng,
        )
        low, high = result.confidence_interval
        if not (math.isfinite(low) and math.isfinite(high)):
            rng = np.random.default_rng(np.random.SeedSequence(list(seed)))
            result = bootstrap(
                (x, y),
                vargha_delaney,
                n_resamples=BOOTSTRAP_RESAMPLES,
                confidence_level=CONFIDENCE,
                method="percentile",
                vectorized=True,
                random_state=rng,
            )
            low, high = result.confidence_interval
    return float(np.clip(low, 0.0, 1.0)), float(np.clip(high, 0.0, 1.0))


def holm(tests: Sequence[PairTest]) -> list[PairTest]:
    """``tests`` with their Holm-adjusted p-values (one family), in their order."""
    m = len(tests)
    order = sorted(range(m), key=lambda i: tests[i].p)
    adjusted = [1.0] * m
    running = 0.0
    for k, i in enumerate(order):
        running = max(running, min(1.0, (m - k) * tests[i].p))
        adjusted[i] = running
    return [dataclasses.replace(t, p_holm=adjusted[i]) for i, t in enumerate(tests)]


def mann_whitney(task: str, a: str, b: str, x: np.ndarray, y: np.ndarray) -> PairTest:
    """The test of ``x`` (treatment a) against ``y`` (treatment b)."""
    if x.size == 0 or y.size == 0:
        raise ValueError(f"{task}: {a} or {b} has no runs to compare")
    result = mannwhitneyu(x, y, alternative="two-sided")
    p = float(result.pvalue)
    if math.isnan(p):  # every value tied: no evidence of a difference
        p = 1.0
    low, high = effect_interval(
        x, y, [zlib.crc32(word.encode()) for word in (task, a, b)]
    )
    return PairTest(
        task=task,
        a=a,
        b=b,
        n_a=int(x.size),
        n_b=int(y.size),
        median_a=float(np.median(x)),
        median_b=float(np.median(y)),
        mean_a=float(np.mean(x)),
        mean_b=float(np.mean(y)),
        u=float(result.statistic),
        p=min(max(p, 0.0), 1.0),
        effect_low=low,
        effect_high=high,
    )


def pairwise_tests(task: str, bests: dict[str, np.ndarray]) -> list[PairTest]:
    """Every pair of treatments, in the paper's order (a before b), one family
    for Holm's correction."""
    return holm(
        [
            mann_whitney(task, a, b, bests[a], bests[b])
            for a, b in itertools.combinations(bests, 2)
            if bests[a].size and bests[b].size
        ]
    )
