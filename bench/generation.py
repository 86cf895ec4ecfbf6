"""Wall time per generation, and the share of it spent outside the simulator.

For every task of the registry (or ``--task``), runs ``--generations`` generations of
``--treatment`` (default NS-SD+, the treatment with the most work outside the
simulator: standardisation, mutual-information weights, novelty) with the paper's
settings - population 200, 10 trials, the best re-evaluated in 50 trials - on the
local evaluator (``--workers``, default every core), writing to a temporary output
directory. The archive is filled to its capacity (1000) after the first generation,
with jittered copies of that generation's SDBC vectors, so novelty is timed at its
largest. The first generation also starts the worker pool and is not counted.

The runner times each phase of a generation: the simulator (the population's trials
and the re-evaluation, SDBC extraction included, in the worker processes) and
everything else (scoring: standardisation, weights, novelty, archive, ranking;
breeding; writing outputs; the checkpoint). The last lines read
``TASK s/gen=S outside=P%`` with P the share outside the simulator (target: at most
10%).

Run: ``.venv/bin/python bench/generation.py`` (options: ``--task``, ``--treatment``,
``--generations``, ``--population``, ``--trials``, ``--workers``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.run.config import (
    EvaluationConfig,
    ExperimentConfig,
    GaConfig,
    load_treatment,
)
from sdbc_evolution.run.evaluators import LocalEvaluator
from sdbc_evolution.run.experiment import Experiment, task_spec
from sdbc_sim.tasks import available_tasks

SIMULATOR_PHASES = ("evaluation", "reevaluation")
OUTSIDE_PHASES = ("scoring", "breeding", "outputs", "checkpoint")
JITTER = 0.05
"""Relative jitter of the synthetic archive entries (of each dimension's SD)."""


def fill_archive(experiment: Experiment, rng: np.random.Generator) -> None:
    """Fills the archive to capacity with jittered copies of the last generation."""
    last = experiment.results.individuals_path(experiment.state.generation - 1)
    with np.load(last) as data:
        # The archive holds the treatment's own raw vectors.
        characterisation = experiment.config.treatment.characterisation
        key = "sdbc"
        if "behaviour" in data.files:
            key = "behaviour"
        elif characterisation is not None and characterisation.kind == "task":
            key = "characterisation"
        pool = data[key].astype(np.float64)
        fitness = data["fitness"]
    capacity = experiment.config.novelty.archive_size
    rows = rng.integers(0, pool.shape[0], capacity)
    spread = pool.std(axis=0) * JITTER
    experiment.state.archive = NoveltyArchive(
        capacity=capacity,
        probability=experiment.config.novelty.archive_probability,
        behaviours=pool[rows] + rng.normal(size=(capacity, pool.shape[1])) * spread,
        fitness=fitness[rows],
        generation=np.zeros(capacity, dtype=np.int64),
    )


def bench_task(task: str, args: argparse.Namespace) -> tuple[float, float]:
    """(seconds per generation, share outside the simulator) of one task."""
    config = ExperimentConfig(
        task=task,
        treatment=load_treatment(args.treatment),
        generations=args.generations + 1,
        ga=GaConfig(population_size=args.population),
        evaluation=EvaluationConfig(trials=args.trials),
    ).resolved()
    totals: dict[str, float] = {}
    walls = []
    with (
        tempfile.TemporaryDirectory() as out,
        LocalEvaluator(task_spec(config), args.workers) as evaluator,
    ):
        experiment = Experiment.create(config, Path(out), evaluator)
        experiment.step()  # starts the pool; not counted
        fill_archive(experiment, np.random.default_rng(0))
        while not experiment.finished:
            start = time.perf_counter()
            experiment.step()
            walls.append(time.perf_counter() - start)
            for phase, seconds in experiment.timings.items():
                totals[phase] = totals.get(phase, 0.0) + seconds
            print(
                f"  {task} generation {experiment.state.generation - 1}: "
                f"{walls[-1]:.2f} s, archive {len(experiment.state.archive)}",
                flush=True,
            )
    wall = sum(walls)
    simulator = sum(totals[p] for p in SIMULATOR_PHASES)
    outside = sum(totals[p] for p in OUTSIDE_PHASES)
    parts = ", ".join(f"{p} {totals[p] / len(walls) * 1e3:.0f} ms" for p in totals)
    print(f"  {task} per generation: {parts}")
    print(
        f"  {task} simulator {simulator / wall:.1%}, outside {outside / wall:.1%}, "
        f"unaccounted {(wall - simulator - outside) / wall:.1%}"
    )
    return wall / len(walls), outside / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", action="append", help="task (repeatable)")
    parser.add_argument(
        "--treatment", default="ns-sd+", help="a paper treatment or a YAML file"
    )
    parser.add_argument(
        "--generations", type=int, default=2, help="timed generations per task"
    )
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args()
    tasks = args.task or sorted(available_tasks())
    workers = args.workers or "all"
    print(
        f"{args.treatment}, population {args.population} x {args.trials} trials, "
        f"workers: {workers}"
    )
    lines = []
    for task in tasks:
        seconds, outside = bench_task(task, args)
        lines.append(f"{task} s/gen={seconds:.2f} outside={outside:.1%}")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
