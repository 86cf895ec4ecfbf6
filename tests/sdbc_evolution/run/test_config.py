"""Typed configuration: defaults from docs/reference-setup.md, clear errors naming
the key."""

from __future__ import annotations

from pathlib import Path

import pytest
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    Treatment,
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
    assert config.treatment is Treatment.NS_TS
    assert config.ga.population_size == 50 and config.ga.mutation_sigma == 1.0
    assert config.ga.elites == 5
    again = tmp_path / "again.yaml"
    again.write_text(dump_config(config.resolved()))
    assert load_config(again) == config.resolved()


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"ga": {"populaton_size": 5}}, r"unknown key.*ga\.populaton_size"),
        ({"colour": "red"}, r"unknown key.*colour"),
        ({"ga": {"population_size": 1}}, r"ga\.population_size: must be at least 2"),
        ({"ga": {"population_size": 10, "elites": 10}}, r"ga\.elites"),
        ({"ga": {"tournament_size": 0}}, r"ga\.tournament_size"),
        ({"ga": {"mutation_probability": 1.2}}, r"ga\.mutation_probability"),
        ({"ga": {"mutation_sigma": -0.5}}, r"ga\.mutation_sigma"),
        ({"ga": {"population_size": 2.5}}, r"ga\.population_size: expected an integer"),
        (
            {"ga": {"population_size": True}},
            r"ga\.population_size: expected an integer",
        ),
        ({"ga": {"mutation_sigma": ".nan"}}, r"ga\.mutation_sigma: expected a number"),
        (
            {"ga": {"mutation_sigma": float("nan")}},
            r"ga\.mutation_sigma: expected a finite",
        ),
        ({"novelty": {"k": 0}}, r"novelty\.k"),
        ({"novelty": {"tie_break": "random"}}, r"novelty\.tie_break"),
        ({"novelty": {"archive_probability": -0.1}}, r"novelty\.archive_probability"),
        ({"weighting": {"fitness_clusters": 1}}, r"weighting: fitness_clusters 1"),
        ({"weighting": {"feature_discretisation": "x"}}, r"weighting\.feature_disc"),
        ({"weighting": {"delta": -1}}, r"^weighting: delta -1"),
        ({"standardisation": {"clip": 0}}, r"^standardisation: clip 0"),
        ({"characterisation": {"delta": 1}}, r"unknown key.*characterisation"),
        ({"evaluation": {"trials": 0}}, r"evaluation\.trials"),
        ({"treatment": "ns-xx"}, r"treatment: 'ns-xx' is not one of"),
        ({"generations": 0}, r"generations: must be at least 1"),
        ({"seed": -1}, r"seed"),
        ({"ga": [1, 2]}, r"ga: expected a mapping"),
        ({"task_config": 3}, r"task_config: expected a mapping"),
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
