"""Stochastic ranking (Runarsson & Yao, IEEE TEC 2000) on fitness and novelty.

Runarsson and Yao balanced an objective against a constraint penalty by a bubble
sort whose every comparison of two neighbours is made on the objective with
probability P_f and on the penalty otherwise. Here the two are fitness and
novelty: a comparison is by fitness with probability ``p_fitness``, by novelty
otherwise, and sweeps stop after ``sweeps`` or at the first sweep without a swap.

It draws from the run's generator (``n - 1`` numbers per sweep), so it says so
(``draws = True``): a run that uses it is still a function of its seed.
"""

from __future__ import annotations

import numpy as np
from sdbc_evolution.ga.rankings import Ranking, RankingContext
from sdbc_sim.settings import Fraction, PositiveInt, settings


@settings
class StochasticRankingOptions:
    """Stochastic ranking's options."""

    p_fitness: Fraction = 0.45
    """P_f, the chance that a comparison is by fitness (Runarsson & Yao: 0.45)."""
    sweeps: PositiveInt | None = None
    """Most bubble-sort sweeps; None: the population's size."""


class StochasticRanking(Ranking):
    """Bubble sort comparing by fitness with probability P_f, else by novelty."""

    options_class = StochasticRankingOptions
    draws = True

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        fitness = context.fitness
        novelty = context.given("novelty", "stochastic_ranking")
        n = context.size
        order = np.arange(n)
        for _ in range(self.options.sweeps or n):
            by_fitness = context.rng.random(n - 1) < self.options.p_fitness
            swapped = False
            for j in range(n - 1):
                key = fitness if by_fitness[j] else novelty
                if key[order[j + 1]] > key[order[j]]:
                    order[j], order[j + 1] = order[j + 1], order[j]
                    swapped = True
            if not swapped:
                break
        return order, np.zeros(n, np.int64)
