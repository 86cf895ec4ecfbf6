"""Rankings of a scored population besides NSGA-II: how fitness and novelty (and,
for some, behaviour neighbourhoods) become the order selection reads.

Every ranking returns ``(order, front)``: individual indices best first, and a
front index per individual (0 for all where the ranking has no fronts). Ties go
to the lower index, so every order is deterministic.

- :func:`fitness_ranking`: fitness alone (Fit).
- :func:`novelty_ranking`: novelty alone (pure novelty search, Lehman & Stanley 2011).
- :func:`local_competition`, then NSGA-II on (novelty, local competition): novelty
  search with local competition (NSLC, Lehman & Stanley 2011). An individual's
  local competition is the share of its k nearest neighbours in behaviour space
  (population and archive, itself excluded, as for novelty) whose fitness it beats.
- :func:`scalarised_ranking`: w F' + (1 - w) rho', F' and rho' min-max normalised
  over the population (a constant objective counts 0): linear scalarisation, as in
  the authors' later code.
- :func:`minimal_criterion_ranking`: individuals whose fitness meets a criterion
  (by default the population's median) come first, by novelty; the others after
  them, by fitness (a minimal-criterion novelty search, after Lehman & Stanley's
  MCNS and the authors' progressive minimal criterion, whose criterion here is the
  population's own median each generation).
"""

from __future__ import annotations

import numpy as np

from sdbc_evolution.ga.novelty import neighbour_distances
from sdbc_evolution.ga.selection import fitness_order


def _ordered(key: np.ndarray) -> np.ndarray:
    """Indices by ``key`` descending, ties to the lower index."""
    return np.lexsort((np.arange(key.size), -key))


def fitness_ranking(fitness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """By fitness alone (:func:`sdbc_evolution.ga.selection.fitness_order`)."""
    return fitness_order(fitness), np.zeros(len(fitness), np.int64)


def novelty_ranking(novelty: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """By novelty alone."""
    return _ordered(np.asarray(novelty, float)), np.zeros(len(novelty), np.int64)


def local_competition(
    population: np.ndarray,
    archive: np.ndarray,
    fitness: np.ndarray,
    archive_fitness: np.ndarray,
    k: int,
) -> np.ndarray:
    """(N,) share of each individual's k nearest neighbours it beats on fitness.

    Neighbours are the other members of the population and the archive, by
    Euclidean distance between the (transformed) behaviour vectors; among equally
    distant neighbours the earlier ones (population first) count.
    """
    population = np.asarray(population, float)
    archive = np.asarray(archive, float).reshape(-1, population.shape[1])
    pool_fitness = np.concatenate([fitness, archive_fitness])
    distances, k_used = neighbour_distances(population, archive, k)
    if k_used == 0:
        return np.zeros(population.shape[0])
    nearest = np.argsort(distances, axis=1, kind="stable")[:, :k_used]
    beaten = fitness[:, None] > pool_fitness[nearest]
    return beaten.mean(axis=1)


def scalarised_ranking(
    fitness: np.ndarray, novelty: np.ndarray, weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """By w F' + (1 - w) rho' (module docstring)."""

    def normalised(values: np.ndarray) -> np.ndarray:
        span = np.ptp(values)
        return (values - values.min()) / span if span > 0 else np.zeros_like(values)

    score = weight * normalised(np.asarray(fitness, float)) + (1.0 - weight) * (
        normalised(np.asarray(novelty, float))
    )
    return _ordered(score), np.zeros(len(fitness), np.int64)


def minimal_criterion_ranking(
    fitness: np.ndarray, novelty: np.ndarray, criterion: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """Those meeting the criterion by novelty, then the rest by fitness; front 0
    for those meeting it, 1 for the others."""
    fitness = np.asarray(fitness, float)
    threshold = float(np.median(fitness)) if criterion is None else criterion
    meets = fitness >= threshold
    index = np.arange(fitness.size)
    key = np.where(meets, np.asarray(novelty, float), fitness)
    order = np.lexsort((index, -key, ~meets))
    return order, (~meets).astype(np.int64)
