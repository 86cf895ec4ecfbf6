"""Feature weighting by mutual information with fitness (NS-SD+, eq. 6 of the paper).

The relevance of behaviour feature k is estimated by the mutual information between
the raw feature values of the current population and its fitness scores; every
standardised dimension is then multiplied by

    w_k = delta + I(F; k),    delta = 0.25,

so that relevant dimensions count more in the behaviour distance and none is ignored.

I(F; k) is computed on discretised variables, in bits:

- fitness F into 10 clusters by 1-D k-means, as the authors did (fewer clusters when
  there are fewer distinct fitness values: each value is then its own cluster);
- feature k into 10 equal-width bins over the population's range, the default here
  (the authors' Weka ranker discretised features itself; the paper leaves the method
  open); k-means, like fitness, is the option;
- ``I = sklearn.metrics.mutual_info_score(F, k) / ln 2`` (nats to bits), at most
  log2(10) = 3.3 bits with 10 classes a side.

Weights are recomputed every generation, or every n generations
(:class:`FeatureWeighting`).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from sdbc_sim.settings import Field, NonNegativeFloat, PositiveInt, settings

Discretisation = Literal["equal_width", "kmeans"]
DISCRETISATIONS: tuple[str, ...] = ("equal_width", "kmeans")


@settings
class WeightingSettings:
    """How NS-SD+ weights its dimensions."""

    delta: NonNegativeFloat = 0.25
    """The least weight of a dimension; the paper: 0.25."""
    fitness_clusters: Annotated[int, Field(ge=2)] = 10
    """Fitness is discretised into this many k-means clusters; the authors: 10."""
    feature_bins: Annotated[int, Field(ge=2)] = 10
    """Each feature is discretised into this many classes."""
    feature_discretisation: Discretisation = "equal_width"
    """"equal_width" bins over the population's range, or "kmeans" clusters as for
    fitness."""
    kmeans_restarts: PositiveInt = 10
    """k-means runs from this many initialisations and keeps the best
    (scikit-learn's n_init)."""
    update_every: PositiveInt = 1
    """Weights are recomputed every this many generations; the paper: every
    generation (1)."""


Seed = int | np.random.Generator | None


def _random_state(seed: Seed) -> int | None:
    """scikit-learn wants an int: draw one from a Generator (so a run stays a
    function of its own generator)."""
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(2**31 - 1))
    return seed


def kmeans_classes(
    values: np.ndarray, n_clusters: int, seed: Seed, restarts: int
) -> np.ndarray:
    """(n,) int labels of a 1-D k-means clustering of ``values`` (n,).

    With at most ``n_clusters`` distinct values each value is its own cluster, which
    is what k-means converges to, without its warnings.
    """
    distinct, inverse = np.unique(values, return_inverse=True)
    if distinct.shape[0] <= n_clusters:
        return inverse
    # Imported here: scikit-learn takes a second to import, and the engine's worker
    # processes import this package for the extractor alone.
    from sklearn.cluster import KMeans

    model = KMeans(
        n_clusters=n_clusters, n_init=restarts, random_state=_random_state(seed)
    )
    return model.fit_predict(values[:, None])


def equal_width_classes(values: np.ndarray, n_bins: int) -> np.ndarray:
    """(n,) int bin of each value among ``n_bins`` equal-width bins spanning the
    values' range (one bin for a constant)."""
    low, high = values.min(), values.max()
    if high <= low:
        return np.zeros(values.shape[0], dtype=np.int64)
    bins = np.floor((values - low) / (high - low) * n_bins).astype(np.int64)
    return np.minimum(bins, n_bins - 1)


def checked_population(
    raw: np.ndarray, fitness: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(n, D) raw vectors and (n,) fitness as float64, refused in one line unless
    their shapes agree and every value is finite (every relevance measure's input)."""
    raw = np.asarray(raw, dtype=np.float64)
    fitness = np.asarray(fitness, dtype=np.float64)
    if raw.ndim != 2:
        raise ValueError(
            f"weighting: raw characterisations must be (n, D), got {raw.shape}"
        )
    if fitness.shape != (raw.shape[0],):
        raise ValueError(
            f"weighting: fitness has shape {fitness.shape}, expected ({raw.shape[0]},) "
            "(one per raw characterisation)"
        )
    if not np.isfinite(raw).all():
        raise ValueError("weighting: raw characterisations hold NaN or infinity")
    if not np.isfinite(fitness).all():
        raise ValueError("weighting: fitness holds NaN or infinity")
    return raw, fitness


def mutual_information(
    raw: np.ndarray,
    fitness: np.ndarray,
    settings: WeightingSettings | None = None,
    seed: Seed = None,
) -> np.ndarray:
    """I(F; k) in bits for every dimension k of the raw characterisations.

    Args:
        raw: (n, D) raw characterisations of the current population.
        fitness: (n,) their fitness scores.
        settings: Discretisation settings.
        seed: Seeds k-means (an int, a Generator to draw one from, or None).

    Returns:
        (D,) mutual information, >= 0.
    """
    from sklearn.metrics import mutual_info_score

    settings = settings or WeightingSettings()
    raw, fitness = checked_population(raw, fitness)
    fitness_classes = kmeans_classes(
        fitness, settings.fitness_clusters, seed, settings.kmeans_restarts
    )
    information = np.empty(raw.shape[1])
    for k in range(raw.shape[1]):
        if settings.feature_discretisation == "kmeans":
            classes = kmeans_classes(
                raw[:, k], settings.feature_bins, seed, settings.kmeans_restarts
            )
        else:
            classes = equal_width_classes(raw[:, k], settings.feature_bins)
        information[k] = mutual_info_score(fitness_classes, classes) / math.log(2.0)
    # The plug-in estimate is >= 0; round-off can leave -1e-17.
    return np.maximum(information, 0.0)


def mutual_information_weights(
    raw: np.ndarray,
    fitness: np.ndarray,
    settings: WeightingSettings | None = None,
    seed: Seed = None,
) -> np.ndarray:
    """w_k = delta + I(F; k) for every dimension (see :func:`mutual_information`)."""
    settings = settings or WeightingSettings()
    return settings.delta + mutual_information(raw, fitness, settings, seed)


class FeatureWeighting:
    """NS-SD+ weights through a run: recomputed every ``update_every`` generations
    from the current population, kept in between.

    Args:
        settings: Weighting settings.
    """

    def __init__(self, settings: WeightingSettings | None = None) -> None:
        self.settings = settings or WeightingSettings()
        self.weights: np.ndarray | None = None
        self.information: np.ndarray | None = None

    def update(
        self, generation: int, raw: np.ndarray, fitness: np.ndarray, seed: Seed = None
    ) -> np.ndarray:
        """The weights for ``generation`` (0-based): recomputed from this
        population's (n, D) raw characterisations and (n,) fitness when the
        generation is a multiple of ``update_every`` or none exist yet."""
        if self.weights is None or generation % self.settings.update_every == 0:
            self.information = mutual_information(raw, fitness, self.settings, seed)
            self.weights = self.settings.delta + self.information
        elif self.weights.shape[0] != np.shape(raw)[1]:
            raise ValueError(
                f"weighting: {np.shape(raw)[1]} dimensions, the weights have "
                f"{self.weights.shape[0]}"
            )
        return self.weights
