"""Typed configuration: defaults from docs/reference-setup.md, clear errors naming
the key."""

from __future__ import annotations

from pathlib import Path

import pytest
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    check_task_config,
    config_from_dict,
    dump_config,
    load_config,
)


def test_defaults_are_spec_numbers() -> None:
    config = ExperimentConfig()
    assert (config.ga.population_size, config.ga.tournament_size, config.ga.elites) == (
        200,
        5,
        5,
    )
    assert (config.ga.mutation_sigma, config.ga.mutation_probability) == (0.5, 0.05)
    assert (
        config.novelty.k,
        config.novelty.archive_probability,
        config.novelty.archive_size,
    ) == (15, 0.03, 1000)
    assert config.weighting.delta == 0.25 and config.weighting.fitness_clusters == 10
    assert config.weighting.update_every == 1 and config.standardisation.clip == 3.0
    assert (config.evaluation.trials, config.evaluation.reevaluation_trials) == (10, 50)
    for task, generations in (
        ("gate_escape", 500),
        ("resource_sharing", 750),
        ("predator_prey", 750),
    ):
        assert config.replace(task=task).resolved_generations == generations


def test_yaml_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "run.yaml"
    path.write_text(
        "task: predator_prey\ntreatment: ns-ts\nseed: 3\n"
        "ga: {population_size: 50, mutation_sigma: 1}\nevaluation: {trials: 4}\n"
    )
    config = load_config(path)
    assert config.treatment.name == "ns-ts"
    assert config.ga.population_size == 50 and config.ga.mutation_sigma == 1.0
    assert config.ga.elites == 5
    again = tmp_path / "again.yaml"
    again.write_text(dump_config(config.resolved()))
    assert load_config(again) == config.resolved()


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (
            {"ga": {"populaton_size": 5}},
            r"^ga\.populaton_size: unknown key; known keys: \[.*population_size",
        ),
        ({"colour": "red"}, r"^colour: unknown key"),
        (
            {"ga": {"population_size": 1}},
            r"ga\.population_size: Input should be greater than or equal to 2, got 1",
        ),
        (
            {"ga": {"population_size": 10, "elites": 10}},
            r"ga\.population_size: 10 is too small.*elites=10",
        ),
        ({"ga": {"tournament_size": 0}}, r"ga\.tournament_size"),
        ({"ga": {"mutation_probability": 1.2}}, r"ga\.mutation_probability"),
        ({"ga": {"mutation_sigma": -0.5}}, r"ga\.mutation_sigma"),
        (
            {"ga": {"population_size": 2.5}},
            r"ga\.population_size: .* valid integer, got 2\.5",
        ),
        (
            {"ga": {"population_size": True}},
            r"ga\.population_size: .* valid integer, got True",
        ),
        ({"ga": {"mutation_sigma": ".nan"}}, r"ga\.mutation_sigma: .* valid number"),
        (
            {"ga": {"mutation_sigma": float("nan")}},
            r"ga\.mutation_sigma: .* finite number, got nan",
        ),
        ({"novelty": {"k": 0}}, r"novelty\.k"),
        ({"novelty": {"tie_break": "random"}}, r"novelty\.tie_break"),
        ({"novelty": {"archive_probability": -0.1}}, r"novelty\.archive_probability"),
        (
            {"weighting": {"fitness_clusters": 1}},
            r"weighting\.fitness_clusters: .* got 1",
        ),
        ({"weighting": {"feature_discretisation": "x"}}, r"weighting\.feature_disc"),
        ({"weighting": {"delta": -1}}, r"^weighting\.delta: .* got -1"),
        ({"standardisation": {"clip": 0}}, r"^standardisation\.clip: .* got 0"),
        ({"characterisation": {"delta": 1}}, r"^characterisation: unknown key"),
        ({"evaluation": {"trials": 0}}, r"evaluation\.trials"),
        ({"treatment": "ns-xx"}, r"treatment: 'ns-xx' is not a preset"),
        ({"generations": 0}, r"generations: .* greater than or equal to 1, got 0"),
        ({"seed": -1}, r"seed"),
        ({"ga": [1, 2]}, r"ga: Input should be a dictionary"),
        ({"task_config": 3}, r"task_config: Input should be a valid dictionary"),
    ],
)
def test_bad_values_name_their_key(data: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        config_from_dict(data)


def test_unknown_task_without_generations_asks_for_them() -> None:
    with pytest.raises(ConfigError, match="generations"):
        _ = ExperimentConfig(task="my_task").resolved_generations


def test_files_that_are_not_configurations(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("ga: {population_size: [\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(bad)
    scalar = tmp_path / "scalar.yaml"
    scalar.write_text("42\n")
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_config(scalar)


@pytest.mark.parametrize(
    ("task_config", "message"),
    [
        (
            {"max_steps": 300.5},
            r"^task_config\.max_steps: Input should be a valid integer, got 300\.5$",
        ),
        ({"max_steps": "300"}, r"^task_config\.max_steps: .* integer, got '300'$"),
        ({"max_steps": float("nan")}, r"^task_config\.max_steps: .*, got nan$"),
        ({"max_speed": float("inf")}, r"^task_config\.max_speed: .* finite number"),
        ({"max_speed": "1"}, r"^task_config\.max_speed: .* valid number, got '1'"),
        (
            {"max_stepz": 3},
            r"^task_config\.max_stepz: unknown key; known keys: .*'max_steps'",
        ),
        ({"max_speed": 3.0}, r"^task_config\.max_speed: 3\.0 must be below"),
    ],
)
def test_task_settings_are_checked_before_any_run(
    task_config: dict, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        check_task_config("gate_escape", task_config)


def test_integers_are_taken_for_numbers_but_nothing_else_is_coerced() -> None:
    config = config_from_dict({"ga": {"mutation_sigma": 1}, "seed": 4})
    assert config.ga.mutation_sigma == 1.0 and isinstance(
        config.ga.mutation_sigma, float
    )
    for data in ({"seed": "4"}, {"seed": 4.0}, {"novelty": {"k": False}}):
        with pytest.raises(ConfigError, match="valid integer"):
            config_from_dict(data)
    with pytest.raises(ConfigError, match="valid string"):
        config_from_dict({"task": 3})


def test_sections_are_keyword_only_and_document_every_field() -> None:
    from sdbc_evolution.run.config import GaConfig
    from sdbc_sim.settings import field_docs

    with pytest.raises(ValueError):
        GaConfig(200)  # type: ignore[misc]
    for section in (ExperimentConfig, GaConfig):
        assert all(field_docs(section).values()), section
