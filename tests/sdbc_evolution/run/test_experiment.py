"""The experiment runner on a fast stand-in evaluator: layout, elitism, resume, bad
checkpoints. (Runs on the real engine are in test_experiment_engine.py.)"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from evolution_helpers import (
    TOY_INFO,
    ToyEvaluator,
    assert_same_run,
    edit_checkpoint_config,
    snapshot,
)
from sdbc_evolution.ga.treatments import PAPER_TREATMENTS
from sdbc_evolution.run import checkpoint as checkpoint_module
from sdbc_evolution.run.checkpoint import CheckpointError
from sdbc_evolution.run.config import config_from_dict
from sdbc_evolution.run.experiment import Experiment, ExperimentError
from sdbc_evolution.run.results import read_generations, read_individuals

TREATMENTS = list(PAPER_TREATMENTS)


def small_config(treatment: str = "ns-ts", generations: int = 5, **sections):
    data = {
        "task": "toy",
        "treatment": treatment,
        "generations": generations,
        "seed": 11,
        "ga": {
            "population_size": 12,
            "tournament_size": 3,
            "elites": 2,
            "mutation_probability": 0.3,
        },
        "novelty": {"k": 4, "archive_probability": 0.3, "archive_size": 5},
        "evaluation": {"trials": 3, "reevaluation_trials": 4},
    }
    for key, value in sections.items():
        data[key] = {**data.get(key, {}), **value}
    return config_from_dict(data)


def run(config, out: Path, workers: int = 2) -> Experiment:
    experiment = Experiment.create(config, out, ToyEvaluator(workers), TOY_INFO)
    experiment.run()
    return experiment


def resume(config, out: Path, workers: int = 2) -> Experiment:
    experiment = Experiment.resume(config, out, ToyEvaluator(workers), TOY_INFO)
    experiment.run()
    return experiment


@pytest.mark.parametrize("treatment", TREATMENTS)
def test_a_run_writes_the_documented_layout(tmp_path: Path, treatment: str) -> None:
    config = small_config(treatment)
    run(config, tmp_path)
    with open(tmp_path / "generations.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0][:3] == ["generation", "best_fitness", "mean_fitness"]
    assert rows[0][-5:] == [f"weight:Toy feature {i}" for i in range(5)]
    assert [r[0] for r in rows[1:]] == ["0", "1", "2", "3", "4"]
    generations = read_generations(tmp_path)
    weights = np.column_stack(
        [generations[f"weight:Toy feature {i}"] for i in range(5)]
    )
    if treatment == "ns-sd+":
        assert (weights >= 0.25).all() and (weights[:, :4] > 0.25).all()
        # Dimension 4 is constant: no information, the floor weight delta.
        assert (weights[:, 4] == 0.25).all()
    else:
        assert np.isnan(weights).all()
    assert (generations["reevaluated_fitness"] > 0).all()
    assert np.isnan(generations["best_novelty"]).all() == (treatment == "fit")
    archive_sizes = generations["archive_size"]
    assert (archive_sizes <= 5).all() and (np.diff(archive_sizes) >= 0).all()
    if treatment == "fit":
        assert (archive_sizes == 0).all()
    assert np.load(tmp_path / "best_genomes.npy").shape == (5, 6)
    individuals = read_individuals(tmp_path)
    assert individuals["sdbc"].shape == (60, 5)
    assert individuals["characterisation"].shape == (60, 3)
    assert individuals["trial_fitness"].shape == (60, 3)
    assert individuals["generation"].tolist() == [
        g for g in range(5) for _ in range(12)
    ]
    assert (tmp_path / "config.yaml").read_text().startswith("task: toy")
    for name in ("config.yaml", "checkpoint.npz", "individuals/gen_00004.npz"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o644


def test_elites_are_the_head_of_the_previous_order(tmp_path: Path) -> None:
    run(small_config("ns-ts"), tmp_path)
    ind = read_individuals(tmp_path)
    best = np.load(tmp_path / "best_genomes.npy")
    for g in range(1, 5):
        now = ind["generation"] == g
        before = ind["generation"] == g - 1
        assert ind["elite"][now].tolist() == [True, True] + [False] * 10
        ranks_before = ind["rank"][before]
        # The two elites come from ranks 0 and 1 of the previous generation...
        assert ranks_before[ind["parent"][now][:2]].tolist() == [0, 1]
        # ...the other parents were tournament winners (any rank but rarely the worst).
        assert ((ind["parent"][now] >= 0) & (ind["parent"][now] < 12)).all()
    assert best.shape == (5, 6)


def test_fit_keeps_the_fittest_genome(tmp_path: Path) -> None:
    experiment = run(small_config("fit"), tmp_path)
    best = np.load(tmp_path / "best_genomes.npy")
    # Under Fit the order is fitness: the best genome of the last generation is the
    # first elite of the next population.
    np.testing.assert_array_equal(experiment.state.population[0], best[-1])


def test_fitness_improves_on_the_toy_problem(tmp_path: Path) -> None:
    config = small_config(
        "fit", generations=25, ga={"population_size": 20, "mutation_sigma": 0.2}
    )
    run(config, tmp_path)
    g = read_generations(tmp_path)
    assert g["best_fitness"][-5:].mean() > 1.5 * g["best_fitness"][0]


@pytest.mark.parametrize("treatment", TREATMENTS)
def test_resume_is_bit_identical(tmp_path: Path, treatment: str) -> None:
    run(small_config(treatment, generations=5), tmp_path / "straight")
    run(small_config(treatment, generations=2), tmp_path / "resumed")
    resume(small_config(treatment, generations=5), tmp_path / "resumed", workers=3)
    assert_same_run(tmp_path / "straight", tmp_path / "resumed")


def test_resume_after_a_crash_between_outputs_and_checkpoint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = small_config("ns-ts", generations=5)
    run(config, tmp_path / "straight")
    real_save = checkpoint_module.save_checkpoint

    def crash_at_3(path, checkpoint):
        if checkpoint.generation == 3:
            raise KeyboardInterrupt
        real_save(path, checkpoint)

    monkeypatch.setattr("sdbc_evolution.run.experiment.save_checkpoint", crash_at_3)
    with pytest.raises(KeyboardInterrupt):
        run(config, tmp_path / "crashed")
    # Generation 2's outputs were written but its checkpoint was not.
    assert len(read_generations(tmp_path / "crashed")["generation"]) == 3
    monkeypatch.setattr("sdbc_evolution.run.experiment.save_checkpoint", real_save)
    resume(config, tmp_path / "crashed")
    assert_same_run(tmp_path / "straight", tmp_path / "crashed")


def test_chunking_does_not_change_a_run(tmp_path: Path) -> None:
    run(small_config("ns-ts"), tmp_path / "one", workers=1)
    run(small_config("ns-ts"), tmp_path / "five", workers=5)
    assert_same_run(tmp_path / "one", tmp_path / "five")


class _Apart(ToyEvaluator):
    """Evaluates every request on its own, as an evaluator of one's own may."""

    def evaluate_together(self, requests):
        return [self.evaluate(g, s) for g, s in requests]


def test_the_next_generation_evaluated_with_the_reevaluation_changes_nothing(
    tmp_path: Path,
) -> None:
    config = small_config("ns-sd+", generations=5)
    joined = ToyEvaluator()
    Experiment.create(config, tmp_path / "joined", joined, TOY_INFO).run()
    apart = _Apart()
    Experiment.create(config, tmp_path / "apart", apart, TOY_INFO).run()
    assert_same_run(tmp_path / "joined", tmp_path / "apart")
    # Generation 0 alone, then each population beside the re-evaluation before
    # it, and the last re-evaluation alone.
    assert (joined.calls, apart.calls) == (6, 10)


def test_an_existing_run_is_not_overwritten(tmp_path: Path) -> None:
    run(small_config(generations=2), tmp_path)
    before = snapshot(tmp_path)
    with pytest.raises(ExperimentError, match="already holds a run"):
        Experiment.create(small_config(), tmp_path, ToyEvaluator(), TOY_INFO)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"ga": {"population_size": 14}},
            r"ga\.population_size: 12 in the checkpoint, 14",
        ),
        ({"seed": 12}, r"seed: 11 in the checkpoint, 12 now"),
        ({"treatment": "fit"}, r"treatment: 'ns-ts' in the checkpoint, 'fit' now"),
        ({"task": "other"}, r"from task 'toy', this run is task 'other'"),
    ],
)
def test_a_checkpoint_of_another_configuration_is_refused(
    tmp_path: Path, change: dict, message: str
) -> None:
    run(small_config(generations=2), tmp_path)
    before = snapshot(tmp_path)
    data = small_config(generations=4).to_dict()
    for key, value in change.items():
        data[key] = {**data[key], **value} if isinstance(value, dict) else value
    with pytest.raises(CheckpointError, match=message):
        Experiment.resume(config_from_dict(data), tmp_path, ToyEvaluator(), TOY_INFO)
    assert snapshot(tmp_path) == before


def test_a_checkpoint_from_before_a_setting_existed_resumes(tmp_path: Path) -> None:
    # As if written before `weighting.update_every` was a setting: its default
    # (every generation) is what the run did, so the run goes on.
    run(small_config(generations=2), tmp_path)
    edit_checkpoint_config(tmp_path, lambda c: c["weighting"].pop("update_every"))
    experiment = Experiment.resume(
        small_config(generations=3), tmp_path, ToyEvaluator(), TOY_INFO
    )
    assert experiment.state.generation == 2
    experiment.close()
    edit_checkpoint_config(tmp_path, lambda c: c["weighting"].update(update_every=5))
    with pytest.raises(CheckpointError, match="weighting.update_every: 5"):
        Experiment.resume(
            small_config(generations=3), tmp_path, ToyEvaluator(), TOY_INFO
        )


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty", "missing"])
def test_a_corrupt_checkpoint_is_refused_and_nothing_changes(
    tmp_path: Path, damage: str
) -> None:
    run(small_config(generations=2), tmp_path)
    path = tmp_path / "checkpoint.npz"
    data = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(bytes(range(256)) * 4)
    elif damage == "empty":
        path.write_bytes(b"")
    else:
        path.unlink()
    before = snapshot(tmp_path)
    expected = "no checkpoint" if damage == "missing" else "corrupt checkpoint"
    with pytest.raises(CheckpointError, match=expected) as refused:
        Experiment.resume(
            small_config(generations=4), tmp_path, ToyEvaluator(), TOY_INFO
        )
    assert snapshot(tmp_path) == before
    if damage in ("garbage", "empty"):
        # Not numpy's advice to load it as a pickle: it is simply not a checkpoint.
        assert str(refused.value) == f"corrupt checkpoint {path}: not an .npz archive"


@pytest.mark.parametrize("left_by", ["this version", "an older version"])
def test_a_run_stopped_before_its_first_generation_goes_on_bit_identically(
    tmp_path: Path, left_by: str
) -> None:
    run(small_config(generations=3), tmp_path / "straight")
    stopped = tmp_path / "stopped"
    Experiment.create(
        small_config(generations=3), stopped, ToyEvaluator(), TOY_INFO
    ).close()
    if left_by == "this version":
        # The generation-0 checkpoint: --resume works from the start.
        resume(small_config(generations=3), stopped)
    else:
        # Older versions left a configuration and an empty generations.csv
        # only: that counts as an empty directory, a fresh start takes it.
        (stopped / "checkpoint.npz").unlink()
        run(small_config(generations=3), stopped)
    assert_same_run(tmp_path / "straight", stopped)


def _damage(out: Path, how: str) -> Path:
    individuals = out / "individuals" / "gen_00001.npz"
    if how == "deleted individuals":
        individuals.unlink()
        return individuals
    if how == "truncated individuals":
        individuals.write_bytes(individuals.read_bytes()[:-40])
        return individuals
    if how == "foreign individuals":
        with np.load(individuals) as data:
            arrays = {k: data[k][:5] if data[k].ndim else data[k] for k in data.files}
        np.savez_compressed(individuals, **arrays)
        return individuals
    if how == "cut csv":
        lines = (out / "generations.csv").read_text().splitlines(keepends=True)
        (out / "generations.csv").write_text("".join(lines[:-1]))
        return out / "generations.csv"
    if how == "duplicated rows":
        lines = (out / "generations.csv").read_text().splitlines(keepends=True)
        (out / "generations.csv").write_text("".join(lines[:2] + lines[1:]))
        return out / "generations.csv"
    best = np.load(out / "best_genomes.npy")
    np.save(out / "best_genomes.npy", best[:1])
    return out / "best_genomes.npy"


DAMAGES = [
    "deleted individuals",
    "truncated individuals",
    "foreign individuals",
    "cut csv",
    "duplicated rows",
    "short best genomes",
]


@pytest.mark.parametrize("how", DAMAGES)
def test_resume_refuses_a_run_whose_outputs_are_damaged_naming_the_file(
    tmp_path: Path, how: str
) -> None:
    run(small_config(generations=3), tmp_path)
    damaged = _damage(tmp_path, how)
    before = snapshot(tmp_path)
    with pytest.raises(CheckpointError, match=re.escape(f"cannot resume: {damaged}")):
        Experiment.resume(
            small_config(generations=4), tmp_path, ToyEvaluator(), TOY_INFO
        )
    assert snapshot(tmp_path) == before


def test_a_checkpoint_missing_an_array_is_corrupt(tmp_path: Path) -> None:
    run(small_config(generations=2), tmp_path)
    path = tmp_path / "checkpoint.npz"
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "archive_fitness"}
    np.savez(path, **arrays)
    with pytest.raises(CheckpointError, match=r"missing \['archive_fitness'\]"):
        Experiment.resume(
            small_config(generations=4), tmp_path, ToyEvaluator(), TOY_INFO
        )


def test_a_finished_run_extends_when_generations_grow(tmp_path: Path) -> None:
    run(small_config(generations=3), tmp_path)
    experiment = Experiment.resume(
        small_config(generations=3), tmp_path, ToyEvaluator(), TOY_INFO
    )
    assert experiment.finished
    experiment.close()
    with pytest.raises(CheckpointError, match="beyond generations=2"):
        Experiment.resume(
            small_config(generations=2), tmp_path, ToyEvaluator(), TOY_INFO
        )


def test_an_individuals_file_holds_the_documented_bytes(tmp_path: Path) -> None:
    # results.py's disk figures rest on N (28 + 4T + 4C + 4D) bytes of arrays per
    # individuals file before compression.
    from sdbc_evolution.run.results import INDIVIDUALS_ARRAYS

    config = small_config(generations=1)
    run(config, tmp_path)
    n, t = config.ga.population_size, config.evaluation.trials
    c, d = TOY_INFO.characterisation_size, len(TOY_INFO.sdbc_names)
    with np.load(tmp_path / "individuals" / "gen_00000.npz") as data:
        assert sorted(data.files) == sorted((*INDIVIDUALS_ARRAYS, "sdbc_names"))
        arrays = sum(data[name].nbytes for name in INDIVIDUALS_ARRAYS)
    assert arrays == n * (28 + 4 * t + 4 * c + 4 * d)
