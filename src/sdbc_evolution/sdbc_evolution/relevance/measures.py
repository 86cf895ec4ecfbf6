"""Relevance of every dimension of raw behaviour vectors to fitness, one population
at a time; weights are then w_k = delta + relevance_k (the paper's eq. 6 form).

Every measure comes from a library (scikit-learn, scipy, dcor); none is a
hand-written estimator:

- ``mi`` (the paper): I(F; k) in bits on discretised variables
  (:func:`sdbc_evolution.sdbc.weighting.mutual_information`).
- ``mi_chance``: I(F; k) minus its chance level, the same estimate with the fitness
  shuffled (:func:`chance_information`, mean over ``shuffles`` permutations), at
  least 0. At small populations the plug-in MI of a feature unrelated to fitness is
  far from 0 (about (b_F - 1)(b_k - 1) / (2 n ln 2) bits, Miller 1955); this keeps
  only what a feature shares with fitness beyond that.
- ``pearson``: |r| (``scipy.stats.pearsonr``); 0 for a constant dimension.
- ``spearman``: |rho| (``scipy.stats.spearmanr``); 0 for a constant dimension.
- ``dcor``: distance correlation (``dcor.distance_correlation``), in [0, 1], which
  also sees non-monotonic dependence.
- ``mrmr``: minimum redundancy, maximum relevance (Peng et al. 2005; with
  ``redundancy: sum``, Battiti's MIFS with beta = 1): dimensions are selected
  greedily by I(F; k) minus the mean (sum) of I(k; j) over the dimensions j selected
  before; a dimension's relevance is that score when it was selected, at least 0. So
  of two copies of one feature, the second counts for little (the paper's extension
  (iii): weighting that removes redundancy). I(k; j) uses the features'
  discretisation of ``mi``.

Each is a part (:class:`~.base.RelevanceMeasure`, registered in :data:`MEASURES`,
open to the entry point group ``sdbc.relevance``). :meth:`RelevanceSpec.compute`
draws exactly one integer from the run's generator (for k-means and shuffles) and
hands it to the measure as its seed, whether or not it uses it, so that the
generator's stream does not depend on the measure's internals.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from sdbc_sim.parts import PartSpec, Registry
from sdbc_sim.settings import PositiveInt, settings
from threadpoolctl import threadpool_limits

from sdbc_evolution.relevance.base import RelevanceMeasure
from sdbc_evolution.sdbc.weighting import (
    WeightingSettings,
    checked_population,
    equal_width_classes,
    kmeans_classes,
    mutual_information,
)

SEED_BOUND = 2**31 - 1
"""Seeds handed to scikit-learn must fit a 32-bit signed integer."""
CHANCE_SEED = 2014
"""Seeds the fitness shuffles of the chance level (with the population's seed)."""


def chance_information(
    raw: np.ndarray,
    fitness: np.ndarray,
    settings: WeightingSettings,
    seed: int,
    shuffles: int = 1,
) -> np.ndarray:
    """(D,) I(F'; k) in bits with F' the fitness in a random order, the mean over
    ``shuffles`` orders: the MI the estimate gives features unrelated to fitness.

    The orders come from ``numpy.random.default_rng((CHANCE_SEED, seed))``, and
    ``seed`` also seeds the k-means, so the level is a function of its arguments.
    """
    rng = np.random.default_rng((CHANCE_SEED, seed))
    return np.mean(
        [
            mutual_information(raw, rng.permutation(fitness), settings, seed)
            for _ in range(shuffles)
        ],
        axis=0,
    )


ENTRY_POINT_GROUP = "sdbc.relevance"
"""Entry point group of relevance measures from other distributions."""


class Mi(RelevanceMeasure):
    """Mutual information with fitness, bits (paper)."""

    def relevance(
        self,
        raw: np.ndarray,
        fitness: np.ndarray,
        weighting: WeightingSettings,
        seed: int,
    ) -> np.ndarray:
        return mutual_information(raw, fitness, weighting, seed)


@settings
class MiChanceOptions:
    """Chance-corrected mutual information."""

    shuffles: PositiveInt = 1
    """Fitness permutations averaged for the chance level."""


class MiChance(RelevanceMeasure):
    """Mutual information minus its chance level."""

    options_class = MiChanceOptions

    def relevance(
        self,
        raw: np.ndarray,
        fitness: np.ndarray,
        weighting: WeightingSettings,
        seed: int,
    ) -> np.ndarray:
        information = mutual_information(raw, fitness, weighting, seed)
        chance = chance_information(
            raw, fitness, weighting, seed, self.options.shuffles
        )
        return np.maximum(information - chance, 0.0)


class Correlation(RelevanceMeasure):
    """|statistic(dimension, fitness)| of every dimension; 0 for a constant
    dimension or fitness."""

    @staticmethod
    @abstractmethod
    def statistic(x: np.ndarray, y: np.ndarray) -> float:
        """The dependence of ``y`` on ``x`` (both (n,), neither constant)."""

    def relevance(
        self,
        raw: np.ndarray,
        fitness: np.ndarray,
        weighting: WeightingSettings,
        seed: int,
    ) -> np.ndarray:
        out = np.zeros(raw.shape[1])
        if np.ptp(fitness) == 0:
            return out
        for k in range(raw.shape[1]):
            if np.ptp(raw[:, k]) > 0:
                out[k] = abs(float(self.statistic(raw[:, k], fitness)))
        return out


class Pearson(Correlation):
    """|Pearson r| with fitness."""

    @staticmethod
    def statistic(x: np.ndarray, y: np.ndarray) -> float:
        from scipy.stats import pearsonr

        return float(pearsonr(x, y).statistic)


class Spearman(Correlation):
    """|Spearman rho| with fitness."""

    @staticmethod
    def statistic(x: np.ndarray, y: np.ndarray) -> float:
        from scipy.stats import spearmanr

        return float(spearmanr(x, y).statistic)


class DistanceCorrelation(Correlation):
    """Distance correlation with fitness."""

    @staticmethod
    def statistic(x: np.ndarray, y: np.ndarray) -> float:
        import dcor

        return float(dcor.distance_correlation(x, y))


def feature_classes(
    raw: np.ndarray, settings: WeightingSettings, seed: int
) -> list[np.ndarray]:
    """Each dimension's discretisation, as ``mi`` makes it."""
    if settings.feature_discretisation == "kmeans":
        return [
            kmeans_classes(
                raw[:, k], settings.feature_bins, seed, settings.kmeans_restarts
            )
            for k in range(raw.shape[1])
        ]
    return [
        equal_width_classes(raw[:, k], settings.feature_bins)
        for k in range(raw.shape[1])
    ]


@settings
class MrmrOptions:
    """Redundancy-aware selection."""

    redundancy: Literal["mean", "sum"] = "mean"
    """Subtract the mean (mRMR) or the sum (MIFS, beta = 1) of the redundancies."""


class Mrmr(RelevanceMeasure):
    """MI less redundancy with selected dimensions."""

    options_class = MrmrOptions

    def relevance(
        self,
        raw: np.ndarray,
        fitness: np.ndarray,
        weighting: WeightingSettings,
        seed: int,
    ) -> np.ndarray:
        from sklearn.metrics import mutual_info_score

        relevance = mutual_information(raw, fitness, weighting, seed)
        classes = feature_classes(raw, weighting, seed)
        d = raw.shape[1]
        redundancy = np.zeros(d)  # sum of I(k; j) over the selected j
        remaining = list(range(d))
        score = np.zeros(d)
        for chosen in range(d):
            divisor = chosen if self.options.redundancy == "mean" and chosen else 1
            candidates = relevance[remaining] - redundancy[remaining] / divisor
            best = remaining[int(np.argmax(candidates))]
            score[best] = candidates.max()
            remaining.remove(best)
            for k in remaining:
                redundancy[k] += mutual_info_score(
                    classes[k], classes[best]
                ) / math.log(2)
        return np.maximum(score, 0.0)


MEASURES: Registry[RelevanceMeasure] = Registry(
    "relevance measure", ENTRY_POINT_GROUP, RelevanceMeasure
)
"""Every relevance measure, by name."""
MEASURES.register("mi", Mi)
MEASURES.register("mi_chance", MiChance)
MEASURES.register("pearson", Pearson)
MEASURES.register("spearman", Spearman)
MEASURES.register("dcor", DistanceCorrelation)
MEASURES.register("mrmr", Mrmr)


@dataclass(frozen=True)
class RelevanceSpec(PartSpec[RelevanceMeasure]):
    """A declared relevance measure and its options."""

    registry = MEASURES

    def compute(
        self,
        raw: np.ndarray,
        fitness: np.ndarray,
        settings: WeightingSettings,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """(D,) relevance of every dimension of ``raw`` (n, D) to ``fitness`` (n,),
        drawing one integer from ``rng``.

        Raises:
            ValueError: Bad input, or a measure's answer that is not (D,) finite
                values of at least 0, in one line naming the measure.
        """
        seed = int(rng.integers(SEED_BOUND))
        raw, fitness = checked_population(raw, fitness)
        # One thread: k-means on a few hundred values gains nothing from more, loses
        # to thread start-up on a busy machine, and the result cannot then depend on
        # the machine's core count.
        with threadpool_limits(1):
            values = self.build().relevance(raw, fitness, settings, seed)
        values = np.asarray(values, dtype=np.float64)
        if values.shape != (raw.shape[1],):
            raise ValueError(
                f"relevance measure {self.name!r} returned shape {values.shape}, "
                f"expected ({raw.shape[1]},)"
            )
        if not (np.isfinite(values).all() and (values >= 0).all()):
            raise ValueError(
                f"relevance measure {self.name!r} returned a value that is not "
                f"finite and at least 0: {values.tolist()}"
            )
        return values


def parse_relevance(declaration: Any, where: str = "relevance") -> RelevanceSpec:
    """A spec from ``name`` or ``{name: {option: value}}``.

    Raises:
        SettingsError: Unknown measure or bad options, naming ``where``.
    """
    return RelevanceSpec.parse(declaration, where)
