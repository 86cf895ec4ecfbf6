"""Shared helpers for the evolution tests: a fast stand-in for the engine, and run
comparisons. (Not a conftest: test directories below have their own.)"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from sdbc_evolution.run.evaluators import Evaluation, Evaluator, TaskInfo, TaskSpec
from sdbc_evolution.run.results import TIME_COLUMNS, read_generations, read_individuals
from sdbc_sim.engine import controller_fitness

TINY_RUN_YAML = """\
task: gate_escape
task_config: {max_steps: 60}
treatment: ns-ts
generations: 2
ga: {population_size: 6, elites: 1, tournament_size: 2}
novelty: {k: 3}
evaluation: {trials: 2, reevaluation_trials: 2}
"""
"""A run on the real engine small enough for a test: 2 generations of 6."""

TOY_INFO = TaskInfo(
    name="toy",
    genome_length=6,
    characterisation_size=3,
    sdbc_names=tuple(f"Toy feature {i}" for i in range(5)),
)


class ToyEvaluator(Evaluator):
    """Evaluates genomes analytically, each trial perturbed by its own seed.

    Fitness of a trial rises as the genome nears a target point; the
    characterisations are smooth functions of the genome plus seeded noise. Like the
    engine, a trial's result depends only on (genome, seed), and chunks are
    evaluated separately so that chunking is exercised.
    """

    spec = TaskSpec("toy")

    def __init__(self, workers: int = 1) -> None:
        self._workers = workers
        self.calls = 0

    @property
    def workers(self) -> int:
        return self._workers

    def close(self) -> None:
        pass

    def _run(self, genomes, seeds, bounds):
        self.calls += 1
        return [self._chunk(genomes[a:b], seeds[a:b]) for a, b in bounds]

    @staticmethod
    def _chunk(genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        g, t = seeds.shape
        noise = np.array(
            [[np.random.default_rng(s).random(4) for s in row] for row in seeds]
        )  # (g, t, 4)
        target = np.linspace(-0.8, 0.8, genomes.shape[1])
        closeness = np.exp(-np.sum((genomes - target) ** 2, axis=1))  # (g,)
        trial_fitness = closeness[:, None] * (0.8 + 0.2 * noise[..., 0])
        characterisation = np.clip(
            np.stack(
                [
                    (genomes[:, 0:1] + 1) / 2 + 0.05 * noise[..., 1],
                    (genomes[:, 1:2] + 1) / 2 + 0.05 * noise[..., 2],
                    np.repeat(closeness[:, None], t, axis=1),
                ],
                axis=-1,
            ),
            0,
            1,
        )
        sdbc = np.concatenate(
            [
                10 * genomes[:, None, :3] + noise[..., 1:4],
                np.repeat(closeness[:, None, None], t, axis=1),
                np.full((g, t, 1), 7.0),  # a constant dimension: SD 0
            ],
            axis=-1,
        )
        return Evaluation(
            fitness=controller_fitness(trial_fitness),
            trial_fitness=trial_fitness,
            behaviours={
                "task": characterisation.mean(axis=1),
                "sdbc": sdbc.mean(axis=1),
            },
        )


def edit_checkpoint_config(out: Path, edit: Callable[[dict[str, Any]], object]) -> None:
    """Rewrites the checkpoint of the run in ``out`` with ``edit`` applied to the
    run configuration it records, as another version of the code could have
    written it."""
    path = out / "checkpoint.npz"
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["meta"]))
    edit(meta["config"])
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez(path, **arrays)


def snapshot(out: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(out)): p.read_bytes()
        for p in sorted(out.rglob("*"))
        if p.is_file()
    }


def assert_same_run(a: Path, b: Path) -> None:
    """Identical outputs, wall-clock columns aside."""
    ga, gb = read_generations(a), read_generations(b)
    assert ga.keys() == gb.keys()
    for column in ga:
        if column not in TIME_COLUMNS:
            np.testing.assert_array_equal(ga[column], gb[column], err_msg=column)
    np.testing.assert_array_equal(
        np.load(a / "best_genomes.npy"), np.load(b / "best_genomes.npy")
    )
    ia, ib = read_individuals(a), read_individuals(b)
    assert ia.keys() == ib.keys()
    for key in ia:
        np.testing.assert_array_equal(ia[key], ib[key], err_msg=key)
    with np.load(a / "checkpoint.npz") as ca, np.load(b / "checkpoint.npz") as cb:
        assert ca.files == cb.files
        for key in ca.files:
            np.testing.assert_array_equal(ca[key], cb[key], err_msg=key)
