"""The physics model of a run (``evaluation.physics``): read from YAML and checked,
carried to every evaluation and to the best's GIF, kept in the run directory, and
held to on resume (a run from before the key existed was rigid)."""

from __future__ import annotations

import typing
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from evolution_helpers import (
    TINY_RUN_YAML,
    TOY_INFO,
    ToyEvaluator,
    edit_checkpoint_config,
)
from sdbc_evolution.run.checkpoint import CheckpointError
from sdbc_evolution.run.config import (
    ConfigError,
    EvaluationConfig,
    config_from_dict,
    dump_config,
    load_config,
)
from sdbc_evolution.run.evaluators import LocalEvaluator, evaluate_chunk
from sdbc_evolution.run.experiment import Experiment, task_spec
from sdbc_evolution.run.request import ConfigRequest, resolve_config

MAX_STEPS = 60
"""Short gate escape trials: robots still meet the walls and each other."""


def gate_escape(physics: str | None = None, **evaluation: Any) -> Any:
    """A tiny gate escape configuration, with ``evaluation.physics`` if given."""
    if physics is not None:
        evaluation["physics"] = physics
    return config_from_dict(
        {
            "task": "gate_escape",
            "task_config": {"max_steps": MAX_STEPS},
            "generations": 2,
            "evaluation": {"trials": 1, "reevaluation_trials": 0, **evaluation},
        }
    )


def batch() -> tuple[np.ndarray, np.ndarray]:
    """2 genomes x 1 trial."""
    rng = np.random.default_rng(3)
    genomes = rng.uniform(-1.0, 1.0, (2, 108))
    seeds = rng.integers(0, 2**63 - 1, (2, 1), dtype=np.int64)
    return genomes, seeds


def test_the_key_defaults_to_rigid_and_offers_the_engines_models(
    tmp_path: Path,
) -> None:
    from sdbc_sim.physics import MODELS

    assert EvaluationConfig().physics == "rigid"
    assert gate_escape().evaluation.physics == "rigid"
    annotation = typing.get_type_hints(EvaluationConfig)["physics"]
    assert typing.get_args(annotation) == MODELS
    path = tmp_path / "run.yaml"
    path.write_text("task: gate_escape\nevaluation: {trials: 2, physics: kinematic}\n")
    config = load_config(path)
    assert config.evaluation.physics == "kinematic"
    assert config.evaluation.trials == 2
    again = tmp_path / "again.yaml"
    again.write_text(dump_config(config.resolved()))
    assert "physics: kinematic" in again.read_text()
    assert load_config(again) == config.resolved()


@pytest.mark.parametrize("value", ["soft", "Kinematic", "", 1, None])
def test_a_bad_model_names_the_key(value: object) -> None:
    with pytest.raises(ConfigError, match=r"^evaluation\.physics: "):
        config_from_dict({"evaluation": {"physics": value}})


def test_the_task_spec_carries_the_model_to_the_engine_settings() -> None:
    from sdbc_sim.engine import EngineSettings
    from sdbc_sim.physics import PhysicsSettings

    for model in ("rigid", "kinematic"):
        spec = task_spec(gate_escape(model))
        assert spec.physics == model
        assert spec.engine_settings() == EngineSettings(
            physics=PhysicsSettings(model=model)
        )


def test_a_kinematic_evaluation_is_the_kinematic_engine() -> None:
    from sdbc_evolution.sdbc.characterisation import SdbcExtractor
    from sdbc_sim.engine import EngineSettings, run_batch
    from sdbc_sim.physics import PhysicsSettings
    from sdbc_sim.tasks import make_task

    genomes, seeds = batch()
    task = make_task("gate_escape", max_steps=MAX_STEPS)
    direct = {}
    for model in ("rigid", "kinematic"):
        extractor = SdbcExtractor()
        result = run_batch(
            task,
            genomes,
            seeds,
            [extractor],
            settings=EngineSettings(physics=PhysicsSettings(model=model)),
        )
        direct[model] = (result, extractor.characterisations().reshape(2, 1, -1))
    # The models do differ on this batch, so the comparisons below can fail.
    assert not np.array_equal(direct["rigid"][1], direct["kinematic"][1])
    for model in ("rigid", "kinematic"):
        evaluation = evaluate_chunk(task_spec(gate_escape(model)), genomes, seeds)
        result, sdbc = direct[model]
        np.testing.assert_array_equal(evaluation.fitness, result.controller_fitness)
        np.testing.assert_array_equal(evaluation.trial_fitness, result.fitness)
        np.testing.assert_array_equal(
            evaluation.characterisation, result.controller_characterisation
        )
        np.testing.assert_array_equal(evaluation.sdbc, sdbc.mean(axis=1))


def test_worker_processes_run_the_models_they_are_given() -> None:
    genomes, seeds = batch()
    spec = task_spec(gate_escape("kinematic"))
    with LocalEvaluator(spec, workers=2) as two:
        pooled = two.evaluate(genomes, seeds)
    alone = evaluate_chunk(spec, genomes, seeds)
    rigid = evaluate_chunk(task_spec(gate_escape("rigid")), genomes, seeds)
    np.testing.assert_array_equal(pooled.sdbc, alone.sdbc)
    np.testing.assert_array_equal(pooled.characterisation, alone.characterisation)
    assert not np.array_equal(pooled.sdbc, rigid.sdbc)


def toy(physics: str | None = None, generations: int = 2) -> Any:
    """A run of the stand-in evaluator (which ignores the physics)."""
    evaluation: dict[str, Any] = {"trials": 2, "reevaluation_trials": 2}
    if physics is not None:
        evaluation["physics"] = physics
    return config_from_dict(
        {
            "task": "toy",
            "generations": generations,
            "seed": 5,
            "ga": {"population_size": 6, "tournament_size": 2, "elites": 1},
            "novelty": {"k": 3},
            "evaluation": evaluation,
        }
    )


def test_the_run_directory_keeps_the_model_and_resume_holds_to_it(
    tmp_path: Path,
) -> None:
    with Experiment.create(toy("kinematic"), tmp_path, ToyEvaluator(), TOY_INFO) as e:
        e.run()
    saved = load_config(tmp_path / "config.yaml")
    assert saved.evaluation.physics == "kinematic"
    # `--resume --out DIR` reads the run's own configuration back.
    request = ConfigRequest(resume=True, out=tmp_path, generations=3)
    resumed = resolve_config(request)
    assert resumed.evaluation.physics == "kinematic"
    with Experiment.resume(resumed, tmp_path, ToyEvaluator(), TOY_INFO) as e:
        assert e.state.generation == 2
        e.run()
    with pytest.raises(
        CheckpointError,
        match=r"evaluation\.physics: 'kinematic' in the checkpoint, 'rigid' now",
    ):
        Experiment.resume(toy("rigid", 4), tmp_path, ToyEvaluator(), TOY_INFO)


def test_a_checkpoint_from_before_the_key_resumes_as_rigid(tmp_path: Path) -> None:
    with Experiment.create(toy(), tmp_path, ToyEvaluator(), TOY_INFO) as e:
        e.run()
    edit_checkpoint_config(tmp_path, lambda c: c["evaluation"].pop("physics"))
    # And the run's config.yaml as an older version wrote it.
    old = (tmp_path / "config.yaml").read_text().replace("  physics: rigid\n", "")
    assert "physics" not in old
    (tmp_path / "config.yaml").write_text(old)
    resumed = resolve_config(ConfigRequest(resume=True, out=tmp_path, generations=3))
    assert resumed.evaluation.physics == "rigid"
    with Experiment.resume(resumed, tmp_path, ToyEvaluator(), TOY_INFO) as e:
        assert e.state.generation == 2
        e.run()
    assert load_config(tmp_path / "config.yaml").evaluation.physics == "rigid"
    with pytest.raises(CheckpointError, match=r"evaluation\.physics: 'rigid'"):
        Experiment.resume(toy("kinematic", 4), tmp_path, ToyEvaluator(), TOY_INFO)


def test_the_command_line_runs_and_renders_with_the_configured_model(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sdbc_sim.render
    from sdbc_evolution.run.cli import main

    rendered: list[Any] = []

    def render_trial(task: Any, genome: Any, seed: int, path: Path, **kw: Any) -> Path:
        rendered.append(kw.get("settings"))
        return path

    monkeypatch.setattr(sdbc_sim.render, "render_trial", render_trial)
    config = tmp_path / "kinematic.yaml"
    text = TINY_RUN_YAML.replace(
        "evaluation: {trials: 2, reevaluation_trials: 2}",
        "evaluation: {trials: 2, reevaluation_trials: 2, physics: kinematic}",
    )
    assert "physics: kinematic" in text
    config.write_text(text)
    out = tmp_path / "run"
    argv = ["--config", str(config), "--out", str(out), "--quiet", "--workers", "1"]
    assert main(argv) == 0
    [settings] = rendered
    assert settings.physics.model == "kinematic"
    assert load_config(out / "config.yaml").evaluation.physics == "kinematic"
    resume = ["--resume", "--out", str(out), "--generations", "3"]
    assert main([*resume, "--quiet", "--workers", "1"]) == 0
    assert [s.physics.model for s in rendered] == ["kinematic", "kinematic"]
