"""Tutorial 03: novelty search over SDBC vectors with pyribs' ProximityArchive, beside
this project's novelty archive, on one task and one budget.

Both searches evaluate their genomes the same way: sdbc's batched simulator
(``run_batch``) on predator-prey, with the SDBC extractor observing every step, so
each controller gets its fitness and its SDBC vector. They start from the same
random population and spend the same number of evaluations. What differs is the
archive and how parents are chosen:

- **pyribs**: ``ProximityArchive`` keeps every behaviour whose novelty (mean
  distance to its k nearest archived neighbours) exceeds a threshold; a
  ``GaussianEmitter`` mutates archived solutions (pyribs' ask/tell ``Scheduler``).
- **sdbc**: ``NoveltyArchive`` keeps a random sample of past behaviours (the paper's
  archive); novelty against population + archive ranks the population, and
  tournaments on that ranking choose the parents of Gaussian mutants.

pyribs' archive stores behaviour vectors for good, so both searches score novelty in
one fixed space (``BehaviourSpace``): the SDBC standardised with the mean and
deviation of a first random population. (This project's own runs standardise
against population + archive again at every generation instead; see
``docs/method.md``.)

    python examples/03_pyribs/pyribs_novelty.py
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from ribs.archives import ProximityArchive
from ribs.emitters import GaussianEmitter
from ribs.schedulers import Scheduler
from scipy.spatial.distance import cdist
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.mutation import gaussian_mutation
from sdbc_evolution.ga.novelty import novelty_scores
from sdbc_evolution.ga.selection import tournament_selection
from sdbc_evolution.sdbc import SdbcExtractor, mean_over_trials
from sdbc_sim.tasks import make_task

from sdbc_sim import run_batch

TASK = make_task("predator_prey", max_steps=150)
TRIALS = 2
"""Trials per controller; its fitness is their harmonic mean (the paper's)."""
K = 15
"""Nearest neighbours of the novelty metric (the paper's k)."""
SIGMA = 0.5
GENE_LOW, GENE_HIGH = -10.0, 10.0
"""Mutation step and gene bounds: this project's GA defaults (ExperimentConfig)."""


class Evaluator:
    """Fitness and SDBC of a batch of genomes, every trial with a fresh seed."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.evaluations = 0

    def __call__(self, genomes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        seeds = self.rng.integers(2**63 - 1, size=(len(genomes), TRIALS))
        extractor = SdbcExtractor()
        result = run_batch(TASK, genomes, seeds, [extractor])
        self.evaluations += len(genomes)
        return result.controller_fitness, mean_over_trials(
            extractor.characterisations(), TRIALS
        )


def distinct_behaviours(behaviours: np.ndarray, radius: float) -> int:
    """Behaviours at least ``radius`` apart among all those seen (a greedy packing):
    a measure of exploration that does not depend on either archive."""
    kept: list[np.ndarray] = []
    for behaviour in behaviours:
        if not kept or cdist(behaviour[None], np.array(kept)).min() >= radius:
            kept.append(behaviour)
    return len(kept)


class BehaviourSpace:
    """The fixed space both searches score novelty in: the SDBC z-scored with the
    mean and deviation of a first population (a dimension constant there keeps its
    unit), and a novelty threshold, that population's median novelty."""

    def __init__(self, first: np.ndarray) -> None:
        self.mean = first.mean(axis=0)
        self.deviation = first.std(axis=0)
        self.deviation[self.deviation < 1e-9] = 1.0
        self.dimensions = first.shape[1]
        z = self(first)
        self.threshold = float(np.median(novelty_scores(z, np.zeros((0, 0)), K)))

    def __call__(self, sdbc: np.ndarray) -> np.ndarray:
        return (sdbc - self.mean) / self.deviation


Result = dict[str, float | int | np.ndarray]


def with_pyribs(
    start: np.ndarray, evaluate: Evaluator, space: BehaviourSpace, generations: int
) -> Result:
    archive = ProximityArchive(
        solution_dim=start.shape[1],
        measure_dim=space.dimensions,
        k_neighbors=K,
        novelty_threshold=space.threshold,
        seed=1,
    )
    emitter = GaussianEmitter(
        archive,
        sigma=SIGMA,
        initial_solutions=start,
        bounds=[(GENE_LOW, GENE_HIGH)] * start.shape[1],
        batch_size=len(start),
        seed=1,
    )
    scheduler = Scheduler(archive, [emitter])
    best, seen = 0.0, []
    for _ in range(generations):
        genomes = scheduler.ask()
        fitness, sdbc = evaluate(genomes)
        behaviours = space(sdbc)
        scheduler.tell(fitness, behaviours)
        best = max(best, float(fitness.max()))
        seen.append(behaviours)
    return {"best": best, "archive": len(archive), "seen": np.concatenate(seen)}


def with_sdbc_archive(
    start: np.ndarray, evaluate: Evaluator, space: BehaviourSpace, generations: int
) -> Result:
    rng = np.random.default_rng(1)
    archive = NoveltyArchive(capacity=1000, probability=0.1)
    population, best, seen = start, 0.0, []
    for generation in range(generations):
        fitness, sdbc = evaluate(population)
        behaviours = space(sdbc)
        novelty = novelty_scores(behaviours, archive.behaviours, K)
        archive.offer(behaviours, fitness, generation, rng)
        # Rank by novelty alone, as pyribs' novelty search does (no fitness objective).
        order = np.lexsort((np.arange(len(novelty)), -novelty))
        positions = np.empty_like(order)
        positions[order] = np.arange(len(order))
        parents = tournament_selection(positions, len(population), 3, rng)
        # Every gene mutated (probability 1), as pyribs' GaussianEmitter does.
        population = gaussian_mutation(
            population[parents], rng, SIGMA, 1.0, GENE_LOW, GENE_HIGH, 100
        )
        best = max(best, float(fitness.max()))
        seen.append(behaviours)
    return {"best": best, "archive": len(archive), "seen": np.concatenate(seen)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=8)
    parser.add_argument("--population", type=int, default=24)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(2014)
    start = rng.uniform(-1.0, 1.0, (args.population, TASK.genome_length))

    _, first = Evaluator(0)(start)
    space = BehaviourSpace(first)
    results = {
        "pyribs ProximityArchive": with_pyribs(
            start, Evaluator(1), space, args.generations
        ),
        "sdbc NoveltyArchive": with_sdbc_archive(
            start, Evaluator(1), space, args.generations
        ),
    }
    evaluations = args.generations * args.population
    print(
        f"{TASK.name}: {evaluations} controllers each, {TRIALS} trials per controller"
    )
    print(
        f"SDBC: {space.dimensions} dimensions; novelty threshold {space.threshold:.2f}"
    )
    print(f"{'search':<26} {'best fitness':>12} {'archive':>8} {'distinct':>9}")
    for name, result in results.items():
        seen = np.asarray(result["seen"])
        distinct = distinct_behaviours(seen, space.threshold)
        print(
            f"{name:<26} {result['best']:>12.4f} {result['archive']:>8} {distinct:>9}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
