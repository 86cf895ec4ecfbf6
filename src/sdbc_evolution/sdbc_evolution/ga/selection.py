"""Parent selection and elitism on a ranking order.

Every treatment reduces a population to one order, best first (fitness for Fit,
NSGA-II front then crowding for the novelty treatments); selection only reads that
order, through each individual's position in it (0 = best).

- Tournament selection: draw ``size`` individuals uniformly with replacement, keep
  the one with the best position (ECJ's ``TournamentSelection``, which the authors
  used).
- Elitism: the first ``elites`` individuals of the order pass to the next
  generation unchanged, and are evaluated again there in fresh trials.
"""

from __future__ import annotations

import numpy as np


def tournament_selection(
    rank_positions: np.ndarray, count: int, size: int, rng: np.random.Generator
) -> np.ndarray:
    """Chooses ``count`` parents by tournaments of ``size``.

    Args:
        rank_positions: (N,) position of every individual in the ranking order
            (0 = best); positions must be distinct.
        count: Number of parents to choose.
        size: Tournament size (>= 1).
        rng: The GA's generator; draws one (count, size) block of indices.

    Returns:
        (count,) int64 indices of the winners.
    """
    rank_positions = np.asarray(rank_positions)
    n = rank_positions.shape[0]
    if size < 1:
        raise ValueError(f"tournament size must be at least 1, got {size}")
    if count < 0:
        raise ValueError(f"number of parents must be >= 0, got {count}")
    if n == 0:
        raise ValueError("cannot select from an empty population")
    contestants = rng.integers(0, n, size=(count, size))
    best = np.argmin(rank_positions[contestants], axis=1)
    return contestants[np.arange(count), best].astype(np.int64)


def elites(order: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` best individuals of a ranking order, best first.

    Args:
        order: (N,) individual indices, best first.
        count: Number of elites, 0 <= count <= N.

    Returns:
        (count,) int64 indices.
    """
    order = np.asarray(order, dtype=np.int64)
    if not 0 <= count <= order.size:
        raise ValueError(f"elites must be in [0, {order.size}], got {count}")
    return order[:count].copy()


def fitness_order(fitness: np.ndarray) -> np.ndarray:
    """Ranking order of the Fit treatment: fitness descending, ties by index.

    Args:
        fitness: (N,) finite fitness values.

    Returns:
        (N,) int64 individual indices, best first.
    """
    fitness = np.asarray(fitness, dtype=np.float64)
    if not np.isfinite(fitness).all():
        raise ValueError("fitness contains NaN or infinite values")
    return np.lexsort((np.arange(fitness.size), -fitness)).astype(np.int64)
