"""Quality of the solutions: best-fitness curves, each run's best, Mann-Whitney U.

The paper's figure 2 and its significance tests, from the run directories:

- the **curve** of a run is the fitness of each generation's best individual
  re-evaluated in fresh trials (``reevaluated_fitness``; without re-evaluation,
  ``best_fitness``, which the selection of the best biases upwards); a treatment's
  curve is the mean over its runs, with the standard error of that mean as a band;
- the **best** of a run is the highest value of its curve: the best controller it
  found, judged on fresh trials;
- **Mann-Whitney U** (two-sided, ``scipy.stats.mannwhitneyu``) compares the bests of
  every pair of treatments on a task. Besides U and p, the table gives the common
  language effect size A = U / (n_a n_b), the chance that a run of treatment a beats
  one of b (ties count half): 0.5 is no difference.
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.stats import mannwhitneyu

from sdbc_evolution.study.digest import RunDigest, TaskDigest


def run_best(run: RunDigest) -> float:
    """The highest value of the run's curve."""
    return float(np.nanmax(run.curve))


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

    @property
    def effect(self) -> float:
        """A = U / (n_a n_b): the chance a run of a beats one of b."""
        return self.u / (self.n_a * self.n_b)


def mann_whitney(task: str, a: str, b: str, x: np.ndarray, y: np.ndarray) -> PairTest:
    """The test of ``x`` (treatment a) against ``y`` (treatment b)."""
    if x.size == 0 or y.size == 0:
        raise ValueError(f"{task}: {a} or {b} has no runs to compare")
    result = mannwhitneyu(x, y, alternative="two-sided")
    p = float(result.pvalue)
    if math.isnan(p):  # every value tied: no evidence of a difference
        p = 1.0
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
    )


def pairwise_tests(task: str, bests: dict[str, np.ndarray]) -> list[PairTest]:
    """Every pair of treatments, in the paper's order (a before b)."""
    return [
        mann_whitney(task, a, b, bests[a], bests[b])
        for a, b in itertools.combinations(bests, 2)
        if bests[a].size and bests[b].size
    ]
