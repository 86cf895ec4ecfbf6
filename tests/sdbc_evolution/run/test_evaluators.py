"""Evaluators on the real engine: any evaluator, any number of workers, same bits."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from sdbc_evolution.characterise.registry import CHARACTERISATIONS, parse
from sdbc_evolution.characterise.sensor_effector import SensorEffectorMean
from sdbc_evolution.run.evaluators import (
    DaskEvaluator,
    Evaluation,
    LocalEvaluator,
    SchedulerUnreachable,
    TaskInfo,
    TaskSpec,
    chunk_bounds,
    evaluate_chunk,
    make_evaluator,
)

# Short trials keep the engine runs to a fraction of a second.
SPEC = TaskSpec("gate_escape", {"max_steps": 80})


def batch(n: int = 5, trials: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(42)
    info = TaskInfo.of(SPEC)
    genomes = rng.uniform(-1, 1, (n, info.genome_length))
    seeds = rng.integers(0, 2**63 - 1, (n, trials), dtype=np.int64)
    return genomes, seeds


def assert_identical(a: Evaluation, b: Evaluation) -> None:
    for name in ("fitness", "trial_fitness", "characterisation", "sdbc"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_chunks_cover_the_batch_in_order() -> None:
    assert chunk_bounds(10, 3) == [(0, 3), (3, 7), (7, 10)]
    assert chunk_bounds(2, 5) == [(0, 1), (1, 2)]
    assert chunk_bounds(1, 1) == [(0, 1)]


def test_task_info_reads_the_task() -> None:
    info = TaskInfo.of(SPEC)
    assert (info.genome_length, info.characterisation_size) == (108, 4)
    assert len(info.sdbc_names) == 21 and info.sdbc_names[-1] == "Simulation length"


def test_one_chunk_is_the_engine_and_the_sdbc_extractor() -> None:
    from sdbc_evolution.sdbc.characterisation import SdbcExtractor
    from sdbc_sim.engine import run_batch
    from sdbc_sim.tasks import make_task

    genomes, seeds = batch()
    evaluation = evaluate_chunk(SPEC, genomes, seeds)
    extractor = SdbcExtractor()
    result = run_batch(
        make_task("gate_escape", max_steps=80), genomes, seeds, [extractor]
    )
    np.testing.assert_array_equal(evaluation.fitness, result.controller_fitness)
    np.testing.assert_array_equal(evaluation.trial_fitness, result.fitness)
    per_trial = extractor.characterisations().reshape(5, 3, -1)
    np.testing.assert_array_equal(evaluation.sdbc, per_trial.mean(axis=1))
    assert evaluation.sdbc.shape == (5, 21)


def test_local_one_and_two_workers_and_dask_agree() -> None:
    from distributed import LocalCluster

    genomes, seeds = batch()
    with LocalEvaluator(SPEC, workers=1) as one:
        reference = one.evaluate(genomes, seeds)
    with LocalEvaluator(SPEC, workers=2) as two:
        assert_identical(reference, two.evaluate(genomes, seeds))
        # A pool is reused across generations.
        assert_identical(reference, two.evaluate(genomes, seeds))
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        DaskEvaluator(SPEC, cluster.scheduler_address) as dask,
    ):
        assert dask.workers == 2
        assert_identical(reference, dask.evaluate(genomes, seeds))


def test_an_unreachable_scheduler_is_a_clear_error() -> None:
    with pytest.raises(
        SchedulerUnreachable, match="no Dask scheduler at .*: connection refused"
    ):
        DaskEvaluator(SPEC, "tcp://127.0.0.1:9", timeout=0.5)
    with pytest.raises(SchedulerUnreachable, match="unknown address scheme"):
        make_evaluator(SPEC, scheduler="carrier-pigeon://roof", timeout=0.5)


def test_bad_batches_and_settings_are_rejected() -> None:
    genomes, seeds = batch()
    evaluator = LocalEvaluator(SPEC, workers=1)
    with pytest.raises(ValueError, match="disagree"):
        evaluator.evaluate(genomes, seeds[:3])
    with pytest.raises(ValueError, match="int64"):
        evaluator.evaluate(genomes, seeds.astype(np.float64))
    with pytest.raises(ValueError, match="genome"):
        evaluator.evaluate(genomes[:, :10], seeds)
    with pytest.raises(ValueError, match="workers must be at least 1"):
        LocalEvaluator(SPEC, workers=0)
    with pytest.raises(ValueError, match="exclude each other"):
        make_evaluator(SPEC, workers=2, scheduler="tcp://127.0.0.1:9")
    with pytest.raises(ValueError, match="unknown task"):
        TaskInfo.of(TaskSpec("gate_scape"))


class _Counting(LocalEvaluator):
    """A local evaluator that keeps the shapes of the seeds it was asked for."""

    def __init__(self, spec: TaskSpec, workers: int) -> None:
        super().__init__(spec, workers)
        self.asked: list[tuple[int, ...]] = []

    def _unchecked(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        self.asked.append(np.shape(seeds))
        return super()._unchecked(genomes, seeds)


def requests() -> list[tuple[np.ndarray, np.ndarray]]:
    """A generation (5 x 3 trials), a re-evaluation (one genome, 4 rows of one
    trial) and 2 x 2 trials."""
    genomes, seeds = batch()
    rng = np.random.default_rng(7)
    best = np.repeat(genomes[2:3], 4, axis=0)
    return [
        (genomes, seeds),
        (best, rng.integers(0, 2**63 - 1, (4, 1), dtype=np.int64)),
        (genomes[:2] * 0.5, rng.integers(0, 2**63 - 1, (2, 2), dtype=np.int64)),
    ]


@pytest.mark.parametrize("workers", [1, 2])
def test_requests_evaluated_together_are_as_evaluated_apart(workers: int) -> None:
    spec = TaskSpec(
        "gate_escape",
        {"max_steps": 80},
        characterisations=(parse("state_count"), parse("sensor_effector_mean")),
    )
    with _Counting(spec, workers) as evaluator:
        together = evaluator.evaluate_together(requests())
        # One batch of a trial per row: 15 + 4 + 4 trials.
        assert evaluator.asked == [(23, 1)]
        apart = [evaluator.evaluate(g, s) for g, s in requests()]
    for a, b in zip(together, apart, strict=True):
        assert_identical(a, b)
        assert a.behaviours.keys() == b.behaviours.keys()
        for key in a.behaviours:
            np.testing.assert_array_equal(a.behaviour(key), b.behaviour(key), key)


class _OwnMean(SensorEffectorMean):
    """A part that does not say its vectors are the mean of its trials."""

    mean_of_trials = False


@pytest.fixture
def own_mean_part() -> Iterator[str]:
    CHARACTERISATIONS.register("test_own_mean", _OwnMean)
    try:
        yield "test_own_mean"
    finally:
        CHARACTERISATIONS._own.pop("test_own_mean")


def test_a_part_not_known_to_average_its_trials_is_evaluated_request_by_request(
    own_mean_part: Any,
) -> None:
    spec = TaskSpec(
        "gate_escape", {"max_steps": 80}, characterisations=(parse(own_mean_part),)
    )
    with _Counting(spec, 1) as evaluator:
        together = evaluator.evaluate_together(requests())
        assert evaluator.asked == [(5, 3), (4, 1), (2, 2)]
    with _Counting(SPEC, 1) as evaluator:
        evaluator.evaluate_together(requests()[:1])
        assert evaluator.asked == [(5, 3)]  # one request: nothing to join
    assert [e.fitness.shape for e in together] == [(5,), (4,), (2,)]
