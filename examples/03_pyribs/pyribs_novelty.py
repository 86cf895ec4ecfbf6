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
- **sdbc**: ``NoveltySearch`` (ask/tell) with a declared treatment of novelty alone:
  its archive keeps a random sample of past behaviours (the paper's, 3 % of each
  generation); novelty against population + archive ranks the population, and its
  GA (elites, tournaments on that ranking, Gaussian mutation of 5 % of the genes)
  breeds the next.

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
from sdbc_evolution.ga.novelty import novelty_scores
from sdbc_evolution.sdbc import mean_over_trials
from sdbc_sim.tasks import make_task

from sdbc_evolution import NoveltySearch, SdbcExtractor
from sdbc_sim import run_batch

TASK = make_task("predator_prey", max_steps=150)
TRIALS = 2
"""Trials per controller; its fitness is their harmonic mean (the paper's)."""
K = 15
"""Nearest neighbours of the novelty metric (the paper's k)."""
SIGMA = 0.5
GENE_LOW, GENE_HIGH = -1.0, 1.0
"""Mutation step and gene bounds: this project's GA defaults (``GaConfig``)."""
NOVELTY_ALONE = {
    "name": "novelty-sdbc",
    "characterisation": "sdbc",
    "ranking": "novelty",
}
"""A declared treatment: novelty alone over the SDBC vectors it is told, as they
are (they come standardised in the fixed space already)."""


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


def with_novelty_search(
    search: NoveltySearch, evaluate: Evaluator, space: BehaviourSpace, generations: int
) -> Result:
    best, seen = 0.0, []
    for _ in range(generations):
        genomes = search.ask()
        fitness, sdbc = evaluate(genomes)
        behaviours = space(sdbc)
        search.tell(fitness, behaviours)
        best = max(best, float(fitness.max()))
        seen.append(behaviours)
    return {"best": best, "archive": len(search.archive), "seen": np.concatenate(seen)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=8)
    parser.add_argument("--population", type=int, default=24)
    args = parser.parse_args(argv)
    search = NoveltySearch(
        NOVELTY_ALONE,
        genome_length=TASK.genome_length,
        population=args.population,
        seed=2014,
    )
    # Its first population (uniform within the gene bounds) is pyribs' too.
    start = search.ask()
    _, first = Evaluator(0)(start)
    space = BehaviourSpace(first)
    results = {
        "pyribs ProximityArchive": with_pyribs(
            start, Evaluator(1), space, args.generations
        ),
        "sdbc NoveltySearch": with_novelty_search(
            search, Evaluator(1), space, args.generations
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
