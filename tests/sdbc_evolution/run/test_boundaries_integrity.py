"""Integrity by content: resume (and so ``sdbc-study run``, which reads a run's
status the same way) checks every cell of ``generations.csv`` the checkpoint
vouches for and every array of the checkpoint, and refuses damage naming the
file, before any generation is evaluated."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from evolution_helpers import TOY_INFO, ToyEvaluator
from sdbc_evolution.run.checkpoint import (
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
)
from sdbc_evolution.run.config import ExperimentConfig, config_from_dict
from sdbc_evolution.run.experiment import Experiment
from sdbc_evolution.run.results import CHECKPOINT_FILE, GENERATIONS_FILE


def toy_config() -> ExperimentConfig:
    return config_from_dict(
        {
            "task": "toy",
            "treatment": "ns-sd+",
            "generations": 3,
            "seed": 2,
            "ga": {"population_size": 8, "elites": 1, "tournament_size": 2},
            "novelty": {"k": 3, "archive_probability": 0.5},
            "evaluation": {"trials": 2, "reevaluation_trials": 2},
        }
    )


@pytest.fixture
def run(tmp_path: Path) -> Path:
    out = tmp_path / "run"
    with Experiment.create(toy_config(), out, ToyEvaluator(), TOY_INFO) as experiment:
        experiment.run()
    return out


class Counting(ToyEvaluator):
    def evaluate(self, genomes, seeds):  # type: ignore[no-untyped-def]
        raise AssertionError("a damaged run was evaluated")


def resume(out: Path) -> None:
    config = toy_config().replace(generations=4)
    with Experiment.resume(config, out, Counting(), TOY_INFO):
        pass


def rewrite_row(out: Path, generation: int, change) -> None:  # type: ignore[no-untyped-def]
    path = out / GENERATIONS_FILE
    lines = path.read_text().splitlines()
    lines[1 + generation] = change(lines[1 + generation])
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda row: row[: len(row) // 2], r"row of generation 1 has \d+ cells"),
        (
            lambda row: row.replace(row.split(",")[1], "abc", 1),
            "row of generation 1 holds 'abc' in best_fitness, not a number",
        ),
        (
            lambda row: ",".join([row.split(",")[0], "inf", *row.split(",")[2:]]),
            "row of generation 1 holds 'inf' in best_fitness",
        ),
        (
            lambda row: ",".join(["1", "0.5", "0.5", "0.5", "", *row.split(",")[5:]]),
            "holds '' in best_index",
        ),
    ],
    ids=["truncated", "abc", "inf", "empty-index"],
)
def test_a_damaged_row_of_generations_csv_is_refused_naming_the_file(
    run: Path, change, message: str
) -> None:
    rewrite_row(run, 1, change)
    with pytest.raises(CheckpointError, match=message) as refused:
        resume(run)
    assert str(run / GENERATIONS_FILE) in str(refused.value)


def damage_checkpoint(out: Path, **arrays: object) -> None:
    path = out / CHECKPOINT_FILE
    checkpoint = load_checkpoint(path, toy_config().to_dict())
    for name, value in arrays.items():
        setattr(checkpoint, name, value)
    save_checkpoint(path, checkpoint)


@pytest.mark.parametrize(
    ("field", "message"),
    [
        ("archive_behaviours", "archive_behaviours holds NaN"),
        ("archive_fitness", "archive_fitness holds NaN"),
        ("weights", "weights holds NaN"),
        ("population", "population holds NaN"),
    ],
)
def test_nan_in_a_checkpoint_array_is_refused_before_any_evaluation(
    run: Path, field: str, message: str
) -> None:
    checkpoint = load_checkpoint(run / CHECKPOINT_FILE, toy_config().to_dict())
    value = np.array(getattr(checkpoint, field), dtype=np.float64)
    assert value.size, f"the run left {field} empty"
    value.flat[0] = np.nan
    damage_checkpoint(run, **{field: value})
    with pytest.raises(CheckpointError, match=message) as refused:
        resume(run)
    assert str(run / CHECKPOINT_FILE) in str(refused.value)


@pytest.mark.parametrize(
    ("state", "message"),
    [
        ("tampered", "ga_rng: not a mapping but str"),
        ({"bit_generator": "PCG64", "state": "x"}, "ga_rng: state should hold"),
        (
            {
                "bit_generator": "PCG64",
                "state": {"state": "1", "inc": 3},
                "has_uint32": 0,
                "uinteger": 0,
            },
            r"ga_rng: state.state should be an integer, got '1'",
        ),
        ({"bit_generator": "Evil"}, "ga_rng: unknown bit generator 'Evil'"),
    ],
    ids=["string", "wrong-keys", "string-int", "unknown"],
)
def test_a_tampered_generator_state_is_refused_naming_the_file(
    run: Path, state: object, message: str
) -> None:
    damage_checkpoint(run, ga_rng=state)
    with pytest.raises(CheckpointError, match=message) as refused:
        resume(run)
    assert str(run / CHECKPOINT_FILE) in str(refused.value)


def test_an_undamaged_run_resumes(run: Path) -> None:
    config = toy_config().replace(generations=4)
    with Experiment.resume(config, run, ToyEvaluator(), TOY_INFO) as experiment:
        experiment.run()
    assert experiment.state.generation == 4
