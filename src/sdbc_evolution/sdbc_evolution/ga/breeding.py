"""Breeding: the paper's generational GA, from a ranking order to the next
population.

The ``elites`` first individuals of the order are copied unchanged; the other
N - elites are bounded-Gaussian mutants (:mod:`.mutation`) of tournament winners
(:mod:`.selection`) on the order's positions. The GA's generator draws, in this
order: the tournaments' (N - elites, tournament_size) indices, then the mutation's
numbers.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from sdbc_sim.settings import (
    Field,
    Fraction,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    check,
    settings,
)

from sdbc_evolution.ga.mutation import gaussian_mutation
from sdbc_evolution.ga.rankings.nsga2 import positions
from sdbc_evolution.ga.selection import elites, tournament_selection


@settings
class GaConfig:
    """The generational GA."""

    population_size: Annotated[int, Field(ge=2)] = 200
    """Individuals per generation."""
    tournament_size: PositiveInt = 5
    """Contestants per tournament when choosing a parent."""
    elites: NonNegativeInt = 5
    """Best individuals copied unchanged into the next generation (and evaluated
    again there in fresh trials)."""
    mutation_sigma: PositiveFloat = 0.5
    """Standard deviation of the Gaussian perturbation of a mutating gene."""
    mutation_probability: Fraction = 0.05
    """Chance that each gene mutates."""
    gene_min: float = -1.0
    """Lower bound of every gene (network weight)."""
    gene_max: float = 1.0
    """Upper bound of every gene."""
    max_redraws: PositiveInt = 100
    """Out-of-bounds mutation draws allowed per gene before a uniform value in the
    bounds is taken instead (ECJ's default)."""

    def __post_init__(self) -> None:
        # Named as the population's problem: a population of 3 to 5 is too small
        # for the default tournament and elites, which the user may not have set.
        need = max(self.tournament_size, self.elites + 1)
        check(
            self.population_size >= need,
            "population_size",
            f"{self.population_size} is too small: must be at least {need} for "
            f"tournament_size={self.tournament_size} and elites={self.elites} "
            "(or set those lower)",
        )
        check(
            self.gene_min < self.gene_max,
            "gene_min",
            f"must be below gene_max={self.gene_max}",
        )


def initial_population(
    ga: GaConfig, genome_length: int, rng: np.random.Generator
) -> np.ndarray:
    """(N, W) genes uniform in the gene bounds: one draw of the whole block."""
    return rng.uniform(ga.gene_min, ga.gene_max, (ga.population_size, genome_length))


def breed(
    population: np.ndarray,
    order: np.ndarray,
    ga: GaConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The next generation of ``population`` ranked by ``order`` (best first).

    Returns:
        (N, W) children, (N,) the index in ``population`` each came from, and
        (N,) bool, which are elites (copied unchanged: the first ``ga.elites``).
    """
    n = population.shape[0]
    kept = elites(order, ga.elites)
    parents = tournament_selection(
        positions(order), n - ga.elites, ga.tournament_size, rng
    )
    mutants = gaussian_mutation(
        population[parents],
        rng,
        sigma=ga.mutation_sigma,
        probability=ga.mutation_probability,
        low=ga.gene_min,
        high=ga.gene_max,
        max_redraws=ga.max_redraws,
    )
    children = np.concatenate([population[kept], mutants])
    parent = np.concatenate([kept, parents])
    elite = np.arange(n) < ga.elites
    return children, parent, elite
