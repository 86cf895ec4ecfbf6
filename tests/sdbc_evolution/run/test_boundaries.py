"""Values are checked where they enter a run, and a run's settings are resolved
completely (every override combined, every limit known) before its directory
exists."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from evolution_helpers import TINY_RUN_YAML, ToyEvaluator
from sdbc_evolution.characterise.evaluation import Evaluation
from sdbc_evolution.graph.live_evaluator import LiveEvaluator
from sdbc_evolution.run.cli import main
from sdbc_evolution.run.evaluators import (
    FITNESS_RANGE,
    DaskEvaluator,
    Evaluator,
    LocalEvaluator,
    TaskSpec,
    ValuesOutOfRange,
    check_values,
    evaluate_chunk,
)

HERE = Path(__file__).resolve().parent
TASKS = HERE / "boundary_tasks.py"


def evaluation(fitness: float = 0.5, task: float = 0.5, sdbc: float = 3.0):
    return Evaluation(
        fitness=np.full(2, fitness),
        trial_fitness=np.full((2, 3), fitness),
        behaviours={"task": np.full((2, 2), task), "sdbc": np.full((2, 4), sdbc)},
    )


def test_values_in_the_contract_pass() -> None:
    check_values(evaluation(fitness=1.0, task=0.0, sdbc=-40.0), TaskSpec("t"))


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"fitness": 20.0}, "trial fitness 20.0 at genome 0, trial 0"),
        ({"fitness": -0.3}, "trial fitness -0.3"),
        ({"fitness": float("nan")}, "trial fitness nan"),
        ({"task": 19.0}, "characterisation 'task' 19.0 at genome 0, dimension 0"),
        ({"sdbc": float("inf")}, "characterisation 'sdbc' inf .* finite"),
    ],
)
def test_values_outside_the_contract_are_refused(values, message) -> None:
    with pytest.raises(ValuesOutOfRange, match=message):
        check_values(evaluation(**values), TaskSpec("t"))


def test_each_task_is_checked_against_its_own_fitness_range() -> None:
    # Predator-prey scores a capture 2 - t/tau; a range of [0, 1] for every task
    # stopped the first kinematic study at its first capture.
    assert TaskSpec("predator_prey").fitness_range == (0.0, 2.0)
    assert TaskSpec("gate_escape").fitness_range == FITNESS_RANGE
    assert TaskSpec("an_outside_simulators_task").fitness_range == FITNESS_RANGE
    check_values(evaluation(fitness=1.9), TaskSpec("predator_prey"))
    with pytest.raises(ValuesOutOfRange, match=r"trial fitness 2.5 .* in \[0, 2\]"):
        check_values(evaluation(fitness=2.5), TaskSpec("predator_prey"))


def test_a_predator_prey_capture_passes_the_value_check() -> None:
    # A genome of the study that stopped, seed 1: its predators catch the prey.
    spec = TaskSpec("predator_prey", physics="kinematic")
    genome = np.load(HERE / "predator_prey_capture.npy")
    result = evaluate_chunk(spec, genome, np.ones((1, 1), dtype=np.int64))
    assert result.trial_fitness[0, 0] > 1.0
    check_values(result, spec)
    # The range every task had before it declared its own.
    with pytest.raises(ValuesOutOfRange):
        check_values(result, TaskSpec("an_outside_simulators_task"))


class OutsideAnswers(ToyEvaluator):
    """What an outside simulator answering fitness 20 hands the run."""

    def _run(self, genomes, seeds, bounds):
        parts = super()._run(genomes, seeds, bounds)
        for part in parts:
            part.trial_fitness = part.trial_fitness * 0 + 20.0
            part.fitness = part.fitness * 0 + 20.0
        return parts


def test_every_evaluator_checks_what_comes_back() -> None:
    # The live graph's evaluator (and through it an outside simulator), the
    # local and the Dask ones all come through Evaluator.evaluate.
    for kind in (LiveEvaluator, LocalEvaluator, DaskEvaluator):
        assert kind.evaluate is Evaluator.evaluate, kind
    genomes, seeds = np.zeros((4, 6)), np.arange(8, dtype=np.int64).reshape(4, 2)
    with pytest.raises(ValuesOutOfRange, match="trial fitness 20.0"):
        OutsideAnswers().evaluate(genomes, seeds)


def tiny_config(tmp_path: Path, task: str) -> Path:
    path = tmp_path / "run.yaml"
    path.write_text(TINY_RUN_YAML.replace("task: gate_escape", f"task: {task}"))
    return path


@pytest.mark.parametrize(
    ("task", "message"),
    [
        ("NegativeFitness", "returned trial fitness -"),
        ("CharacterisationNineteen", "returned characterisation 'task' "),
        ("MissingGroup", "fails its first trial: ValueError: task 'gate_escape', "
         "step 1: 2 groups in the state, 3 in the description"),
    ],
)  # fmt: skip
def test_a_task_that_breaks_the_contract_is_one_line_before_its_run_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], task: str, message: str
) -> None:
    config = tiny_config(tmp_path, f"{TASKS}:{task}")
    out = tmp_path / "run"
    argv = ["--config", str(config), "--out", str(out), "--workers", "1"]
    assert main([*argv, "--quiet", "--no-gif"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_values_out_of_range_mid_run_stop_it_before_the_generation_is_written(
    tmp_path: Path,
) -> None:
    from evolution_helpers import TOY_INFO
    from sdbc_evolution.run.config import config_from_dict
    from sdbc_evolution.run.experiment import Experiment
    from sdbc_evolution.run.results import read_generations

    config = config_from_dict(
        {
            "task": "toy",
            "generations": 3,
            "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
            "novelty": {"k": 3},
            "evaluation": {"trials": 2, "reevaluation_trials": 0},
        }
    )
    out = tmp_path / "run"
    with Experiment.create(config, out, ToyEvaluator(), TOY_INFO) as experiment:
        experiment.run()
    with (
        Experiment.resume(
            config.replace(generations=5), out, OutsideAnswers(), TOY_INFO
        ) as experiment,
        pytest.raises(ValuesOutOfRange, match="trial fitness 20.0"),
    ):
        experiment.run()
    assert len(read_generations(out)["generation"]) == 3


def test_combined_evaluation_overrides_all_hold() -> None:
    from sdbc_evolution.run.request import ConfigRequest, resolve_config

    config = resolve_config(ConfigRequest(trials=3, physics="kinematic"))
    assert (config.evaluation.trials, config.evaluation.physics) == (3, "kinematic")
    config = resolve_config(
        ConfigRequest(population=12, trials=4, physics="kinematic", generations=5)
    )
    assert config.ga.population_size == 12 and config.generations == 5
    assert (config.evaluation.trials, config.evaluation.physics) == (4, "kinematic")


def test_trials_and_physics_combined_on_the_command_line_both_reach_the_run(
    tmp_path: Path,
) -> None:
    # The file says 2 trials: were each override applied to the file's evaluation
    # section, --physics (applied last) would bring the 2 back.
    from sdbc_evolution.run.config import load_config
    from sdbc_evolution.run.results import CONFIG_FILE

    out = tmp_path / "run"
    argv = ["--config", str(tiny_config(tmp_path, "gate_escape")), "--out", str(out),
            "--trials", "3", "--physics", "kinematic", "--workers", "1",
            "--quiet", "--no-gif"]  # fmt: skip
    assert main(argv) == 0
    evaluation = load_config(out / CONFIG_FILE).evaluation
    assert (evaluation.trials, evaluation.physics) == (3, "kinematic")


def test_a_config_of_500_nested_lists_is_one_line_naming_the_depth_limit(
    tmp_path: Path,
) -> None:
    # As a user runs it: a RecursionError would print thousands of lines.
    import os
    import subprocess
    import sys

    from sdbc_sim.limits import CONFIG_DEPTH

    config = tmp_path / "nested.yaml"
    config.write_text("[" * 500 + "]" * 500 + "\n")
    assert config.stat().st_size <= 1024
    out = tmp_path / "run"
    done = subprocess.run(
        [sys.executable, "-m", "sdbc_evolution.run.cli", "--config", str(config),
         "--out", str(out), "--quiet", "--no-gif"],
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    err = done.stderr.strip()
    assert done.returncode == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"nested deeper than {CONFIG_DEPTH} levels (CONFIG_DEPTH)" in err
    assert not out.exists()


def test_a_novelty_k_no_generation_can_reach_is_refused_and_a_large_one_noted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from sdbc_evolution.run.config import ConfigError, config_from_dict

    small = {"ga": {"population_size": 10}, "novelty": {"archive_size": 20}}
    with pytest.raises(ConfigError, match=r"novelty.k: 500 is more than the 29"):
        config_from_dict({**small, "novelty": {"k": 500, "archive_size": 20}})
    config = config_from_dict({"ga": {"population_size": 10}, "novelty": {"k": 500}})
    [note] = config.notes()
    assert "novelty.k=500 is more than the 9 other individuals" in note
    assert "until the archive holds 491 entries" in note
    assert config_from_dict({"ga": {"population_size": 16}}).notes() == []
    fit = {"ga": {"population_size": 10}, "novelty": {"k": 500}, "treatment": "fit"}
    assert config_from_dict(fit).notes() == []  # Fit computes no novelty


def test_workers_are_bounded_and_counted_in_the_memory_check(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from sdbc_evolution.run.config import config_from_dict
    from sdbc_evolution.run.evaluators import TaskInfo
    from sdbc_evolution.run.experiment import task_spec
    from sdbc_evolution.run.footprint import run_footprint
    from sdbc_sim.limits import MAX_WORKERS, WORKER_BYTES

    out = tmp_path / "run"
    argv = ["--out", str(out), "--quiet", "--no-gif"]
    assert main([*argv, "--workers", str(MAX_WORKERS + 1)]) == 2
    err = capsys.readouterr().err
    assert f"--workers: must be at most MAX_WORKERS={MAX_WORKERS}" in err
    assert not out.exists()
    config = config_from_dict({"ga": {"population_size": 10}})
    info = TaskInfo.of(task_spec(config))
    one = run_footprint(config, info, workers=1)
    many = run_footprint(config, info, workers=100_000)
    # One process per individual at most: 10, not 100 000.
    assert many.total - one.total == 10 * WORKER_BYTES


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--connect-timeout", "1e300", "--scheduler", "tcp://127.0.0.1:9"],
            "--connect-timeout: must be in (0, MAX_CONNECT_TIMEOUT=86400]",
        ),
        (["--connect-timeout", "nan"], "--connect-timeout: must be in"),
    ],
)
def test_evaluator_flags_beyond_their_limits_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv, message
) -> None:
    out = tmp_path / "run"
    assert main([*argv, "--out", str(out), "--quiet", "--no-gif"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_max_steps_beyond_the_limit_is_refused_before_the_run_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "run.yaml"
    config.write_text(
        TINY_RUN_YAML.replace("{max_steps: 60}", "{max_steps: 1000000000000}")
    )
    out = tmp_path / "run"
    assert main(["--config", str(config), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "task_config.max_steps: 1000000000000 is more than MAX_STEPS" in err
    assert len(err.splitlines()) == 1 and not out.exists()


def test_a_small_preset_without_generations_is_refused() -> None:
    from sdbc_evolution.study.presets import PresetError, load_preset, preset_from_dict

    small = {
        "name": "mine",
        "tasks": ["gate_escape", "predator_prey"],
        "generations": {"gate_escape": 5},
        "experiment": {"ga": {"population_size": 20}},
    }
    with pytest.raises(PresetError, match=r"generations: not given for \['predator"):
        preset_from_dict(small)
    preset_from_dict({**small, "generations": {"gate_escape": 5, "predator_prey": 5}})
    # At the paper's own scale, the paper's generations are what it asks for.
    assert load_preset("paper").generations_of("gate_escape") == 500


def test_resume_runs_no_task_file_named_by_the_run_directory_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run directory is data: whoever could write its config.yaml must not
    choose the code that --resume imports."""
    evil = tmp_path / "evil.py"
    marker = tmp_path / "imported"
    evil.write_text(
        f"from pathlib import Path\nPath({str(marker)!r}).write_text('ran')\n"
        "from sdbc_sim.tasks.gate_escape import GateEscape as Evil\n"
    )
    out = tmp_path / "run"
    assert main(["--config", str(tiny_config(tmp_path, "gate_escape")), "--out",
                 str(out), "--quiet", "--no-gif", "--workers", "1"]) == 0  # fmt: skip
    config = out / "config.yaml"
    config.write_text(
        config.read_text().replace("task: gate_escape", f"task: {evil}:Evil")
    )
    capsys.readouterr()
    assert main(["--resume", "--out", str(out), "--quiet", "--no-gif"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"names the task file {evil}:Evil" in err and "add --task" in err
    assert len(err.splitlines()) == 1 and not marker.exists()


def test_resume_of_a_task_file_the_user_names_goes_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from sdbc_evolution.run.config import ConfigError
    from sdbc_evolution.run.request import ConfigRequest, resolve_config

    task = f"{HERE / 'evolution_helpers.py'}:Nothing"
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.yaml").write_text(f"task: {task}\ngenerations: 2\n")
    with pytest.raises(ConfigError, match="add --task"):
        resolve_config(ConfigRequest(resume=True, out=out))
    config = resolve_config(ConfigRequest(resume=True, out=out, task=task))
    assert config.task == task
