"""One function resolves a run's configuration for the command line and the node."""

from __future__ import annotations

from pathlib import Path

import pytest
from sdbc_evolution.ga.treatments import PRESETS
from sdbc_evolution.run.checkpoint import CheckpointError
from sdbc_evolution.run.config import ConfigError, quickstart_config
from sdbc_evolution.run.request import ConfigRequest, default_out, resolve_config

CONFIGS = Path(__file__).resolve().parents[3] / "configs"


def test_no_request_is_the_quickstart_with_its_defaults_filled_in() -> None:
    assert resolve_config(ConfigRequest()) == quickstart_config().resolved()


def test_overrides_go_on_top_of_the_file() -> None:
    config = resolve_config(
        ConfigRequest(
            config=CONFIGS / "paper" / "gate_escape.yaml",
            task="predator_prey",
            treatment="fit",
            generations=3,
            population=12,
            trials=2,
            seed=9,
            task_config={"max_steps": 40},
        )
    )
    assert (config.task, config.treatment, config.generations, config.seed) == (
        "predator_prey",
        PRESETS["fit"],
        3,
        9,
    )
    assert config.ga.population_size == 12 and config.evaluation.trials == 2
    assert config.task_config == {"max_steps": 40}


def test_resuming_reads_the_runs_own_configuration(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="--resume needs --out"):
        resolve_config(ConfigRequest(resume=True))
    with pytest.raises(CheckpointError, match="holds no run"):
        resolve_config(ConfigRequest(resume=True, out=tmp_path))
    (tmp_path / "config.yaml").write_text("task: resource_sharing\n")
    config = resolve_config(ConfigRequest(resume=True, out=tmp_path))
    assert config.task == "resource_sharing"


def test_a_bad_override_is_a_config_error_naming_it() -> None:
    with pytest.raises(ConfigError, match="population"):
        resolve_config(ConfigRequest(population=0))


def test_the_default_output_directory_is_numbered_when_taken(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    config = resolve_config(ConfigRequest())
    first = default_out(config)
    assert first == Path("results") / f"gate_escape-ns-sd+-seed{config.seed}"
    first.mkdir(parents=True)
    assert default_out(config) == first.with_name(first.name + "-2")


def test_a_run_folder_is_named_after_the_task_whatever_names_it() -> None:
    from sdbc_evolution.run.config import ExperimentConfig
    from sdbc_evolution.run.request import default_out

    by_module = ExperimentConfig(task="sdbc_sim.tasks.gate_escape:GateEscape", seed=3)
    assert default_out(by_module).name.startswith("gate_escape-ns-sd+-seed3")
    elsewhere = ExperimentConfig(task="drone/fleet", generations=3)
    assert "/" not in default_out(elsewhere).name


def test_the_physics_model_is_an_override_checked_as_the_file_would_be() -> None:
    assert resolve_config(ConfigRequest(physics="kinematic")).evaluation.physics == (
        "kinematic"
    )
    assert resolve_config(ConfigRequest()).evaluation.physics == "rigid"
    with pytest.raises(ConfigError, match="evaluation.physics"):
        resolve_config(ConfigRequest(physics="soft"))
