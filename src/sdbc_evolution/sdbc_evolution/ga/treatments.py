"""The four treatments: how a generation's evaluation becomes a ranking order.

- **Fit**: order by fitness alone; no novelty, no archive.
- **NS-TS**: novelty on the task-specific characterisation (each value already in
  [0, 1], used as it is, as in the authors' code).
- **NS-SD**: novelty on the SDBC, z-scored against population + archive and clipped
  to +-clip (unweighted; ``sdbc_evolution.sdbc.standardise``).
- **NS-SD+**: as NS-SD, each dimension k multiplied by w_k = delta + I(F; k), the
  mutual information between that raw feature and fitness in the current
  population, recomputed every ``weighting.update_every`` generations.

Every novelty treatment then scores novelty against population + archive (k nearest
neighbours), offers the generation to the archive (raw vectors), and ranks on
(fitness, novelty) by non-dominated front and crowding distance (NSGA-II).

One generation, in the order the GA's generator is used (the order is part of the
bit-identical resume contract): [NS-SD+ on a weight generation: one integer seeds
the k-means of the fitness discretisation], then the archive's draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.novelty import novelty_scores
from sdbc_evolution.ga.rankings.nsga2 import nsga2_order
from sdbc_evolution.ga.selection import fitness_order
from sdbc_evolution.run.config import NoveltyConfig, Treatment
from sdbc_evolution.run.evaluators import Evaluation
from sdbc_evolution.sdbc.standardise import StandardisationSettings, standardise
from sdbc_evolution.sdbc.weighting import WeightingSettings, mutual_information_weights

SEED_BOUND = 2**31 - 1
"""Seeds handed to scikit-learn must fit a 32-bit signed integer."""


@dataclass
class GenerationScores:
    """How a treatment scored one generation.

    Attributes:
        order: (N,) individual indices, best first; selection reads only this.
        novelty: (N,) novelty scores; NaN for Fit.
        front: (N,) non-dominated front of each individual; 0 for Fit.
        weights: (D,) the SDBC weights in force (NS-SD+); None otherwise.
        archived: (N,) bool, which individuals entered the archive.
    """

    order: np.ndarray
    novelty: np.ndarray
    front: np.ndarray
    weights: np.ndarray | None
    archived: np.ndarray


def behaviour_vectors(
    treatment: Treatment, evaluation: Evaluation
) -> np.ndarray | None:
    """The raw behaviour vectors a treatment compares (None for Fit)."""
    if treatment is Treatment.FIT:
        return None
    if treatment is Treatment.NS_TS:
        return evaluation.characterisation
    return evaluation.sdbc


def score_generation(
    treatment: Treatment,
    evaluation: Evaluation,
    archive: NoveltyArchive,
    weights: np.ndarray | None,
    generation: int,
    rng: np.random.Generator,
    novelty: NoveltyConfig,
    standardisation: StandardisationSettings,
    weighting: WeightingSettings,
) -> GenerationScores:
    """Scores and ranks one evaluated generation, updating the archive.

    Args:
        treatment: Which treatment.
        evaluation: The generation's evaluation.
        archive: The novelty archive (changed in place).
        weights: NS-SD+ weights in force from an earlier generation, or None.
        generation: Index of this generation (0-based).
        rng: The GA's generator.
        novelty: Novelty settings.
        standardisation: SDBC standardisation settings (NS-SD, NS-SD+).
        weighting: NS-SD+ weighting settings.
    """
    fitness = evaluation.fitness
    n = fitness.shape[0]
    raw = behaviour_vectors(treatment, evaluation)
    if raw is None:
        return GenerationScores(
            order=fitness_order(fitness),
            novelty=np.full(n, np.nan),
            front=np.zeros(n, dtype=np.int64),
            weights=None,
            archived=np.zeros(n, dtype=bool),
        )
    if treatment is Treatment.NS_TS:
        population, archived_vectors = raw, archive.behaviours
    else:
        population, archived_vectors = standardise(
            raw, archive.behaviours, standardisation
        )
    if treatment is Treatment.NS_SD_PLUS:
        if weights is None or generation % weighting.update_every == 0:
            weights = sdbc_weights(raw, fitness, weighting, rng)
        population = population * weights
        archived_vectors = archived_vectors * weights
    else:
        weights = None
    scores = novelty_scores(population, archived_vectors, novelty.k)
    archived = archive.offer(raw, fitness, generation, rng)
    order, front, _ = nsga2_order(
        np.column_stack([fitness, scores]), tie_break=novelty.tie_break
    )
    return GenerationScores(
        order=order, novelty=scores, front=front, weights=weights, archived=archived
    )


def sdbc_weights(
    raw: np.ndarray,
    fitness: np.ndarray,
    weighting: WeightingSettings,
    rng: np.random.Generator,
) -> np.ndarray:
    """NS-SD+ weights w_k = delta + I(F; k) on the current population.

    Draws exactly one integer from ``rng`` to seed the k-means discretisation,
    whether or not k-means ends up running.
    """
    seed = int(rng.integers(SEED_BOUND))
    # One thread: k-means on a few hundred values gains nothing from more, loses
    # to thread start-up on a busy machine (100 vs 380 ms measured under load), and
    # the weights cannot then depend on the machine's core count.
    with threadpool_limits(1):
        weights = mutual_information_weights(raw, fitness, weighting, seed)
    return np.asarray(weights, dtype=np.float64)
