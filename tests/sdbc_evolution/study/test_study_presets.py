"""Study presets: the shipped ones, and bad presets named before any run."""

from __future__ import annotations

from pathlib import Path

import pytest
from sdbc_evolution.ga.treatments import PAPER_TREATMENTS, PRESETS
from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.study.paper import PAPER_TASKS
from sdbc_evolution.study.presets import (
    PRESET_NAMES,
    PresetError,
    StudyPreset,
    dump_preset,
    load_preset,
    load_preset_file,
    preset_from_dict,
)
from study_helpers import TINY


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_shipped_presets_load_and_hold_every_task_and_treatment(name: str) -> None:
    preset = load_preset(name)
    assert preset.name == name
    beyond = {"aggregation", "foraging"}
    assert set(preset.tasks) == (
        beyond if name == "local_new_tasks" else set(PAPER_TASKS)
    )
    assert [t.name for t in preset.treatments] == list(PAPER_TREATMENTS)
    assert preset.description


def test_paper_preset_is_spec_settings() -> None:
    paper = load_preset("paper")
    assert paper.runs == 20
    for task, generations in zip(PAPER_TASKS, (500, 750, 750), strict=True):
        for treatment in PAPER_TREATMENTS:
            config = paper.experiment_config(task, treatment, 7)
            assert config == ExperimentConfig(
                task=task, treatment=PRESETS[treatment], seed=7, generations=generations
            )


def test_local_preset_has_at_least_ten_runs_and_smoke_two() -> None:
    assert load_preset("local").runs >= 10
    assert load_preset("smoke").runs == 2


def test_preset_round_trips_through_yaml(tmp_path: Path) -> None:
    preset = preset_from_dict(TINY)
    path = tmp_path / "tiny.yaml"
    path.write_text(dump_preset(preset))
    assert load_preset_file(path).to_dict() == preset.to_dict()


def test_run_configuration_takes_task_generations_and_task_settings() -> None:
    preset = preset_from_dict(TINY)
    config = preset.experiment_config("gate_escape", "fit", 3)
    assert config.generations == 2
    assert config.task_config == {"max_steps": 60}
    assert config.ga.population_size == 6
    assert config.treatment is PRESETS["fit"] and config.seed == 3


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"runs": 0}, "runs"),
        ({"colour": "red"}, "unknown key"),
        ({"treatments": ["fit", "ns-xx"]}, "treatments"),
        ({"tasks": []}, "tasks"),
        ({"tasks": ["gate_escape", "gate_escape"]}, "duplicates"),
        ({"generations": {"predator_prey": 5}}, "generations"),
        ({"generations": {"gate_escape": 0}}, "generations.gate_escape"),
        ({"experiment": {"seed": 3}}, "may not set"),
        ({"experiment": {"ga": {"population_size": 1}}}, "ga.population_size"),
        ({"experiment": {"ga": {"populaton_size": 10}}}, "unknown key"),
        ({"task_config": {"gate_escape": {"max_stepz": 3}}}, "max_stepz"),
        (
            {
                "tasks": ["no_such_task"],
                "generations": {"no_such_task": 3},
                "task_config": {},
            },
            "unknown task 'no_such_task'",
        ),
        ({"seed": -1}, "seed"),
        (
            {
                "predictions": [
                    {"statement": "x", "a": "ns-sd", "b": "fit", "rule": "not_below"}
                ]
            },
            r"predictions\.0\.a: 'ns-sd' is not a treatment of the study",
        ),
        (
            {
                "predictions": [
                    {"statement": "x", "a": "fit", "b": "fit", "rule": "above"}
                ]
            },
            "predictions.0: compares a treatment with itself",
        ),
        (
            {
                "predictions": [
                    {"statement": "x", "a": "fit", "b": "ns-sd+", "rule": "above"},
                    {"statement": "y", "a": "fit", "b": "ns-sd+", "rule": "bigger"},
                ]
            },
            "predictions.1.rule",
        ),
        (
            {
                "predictions": [
                    {
                        "statement": "x",
                        "a": "fit",
                        "b": "ns-sd+",
                        "rule": "above",
                        "tasks": ["predator_prey"],
                    }
                ]
            },
            r"predictions\.0\.tasks: not in the study: \['predator_prey'\]",
        ),
    ],
)
def test_bad_presets_are_named(change: dict, message: str) -> None:
    with pytest.raises(PresetError, match=message):
        preset_from_dict({**TINY, **change})


def test_unknown_preset_name_and_unreadable_file(tmp_path: Path) -> None:
    with pytest.raises(PresetError, match="unknown preset"):
        load_preset("huge")
    bad = tmp_path / "bad.yaml"
    bad.write_text("runs: [1,\n")
    with pytest.raises(PresetError, match="not valid YAML"):
        load_preset(str(bad))
    with pytest.raises(PresetError, match="cannot read"):
        load_preset(str(tmp_path / "absent.yaml"))


def test_defaults_are_the_paper_study() -> None:
    preset = StudyPreset(name="x")
    assert preset.runs == 20 and preset.sizes()["population"] == 200


def test_the_population_200_preset_tests_ns_sd_plus_on_predator_prey() -> None:
    preset = load_preset("pp_pop200")
    assert preset.tasks == ("predator_prey",) or list(preset.tasks) == ["predator_prey"]
    assert [t.name for t in preset.treatments] == ["ns-sd", "ns-sd+", "ns-sd+chance"]
    for treatment in preset.treatments:
        config = preset.experiment_config("predator_prey", treatment, 0)
        assert config.ga.population_size == 200
    assert preset.runs == 10
    chance = preset.treatments[2].transforms[-1].options.measure.name
    assert chance == "mi_chance"
    assert [(p.a, p.b, p.rule) for p in preset.predictions] == [
        ("ns-sd+", "ns-sd", "not_below"),
        ("ns-sd+chance", "ns-sd", "not_below"),
    ]


def test_new_studies_share_no_run_seed_with_the_committed_ones(tmp_path: Path) -> None:
    """The studies of issue 35 are independent of the earlier ones: none of their
    run seeds (nor champion seeds) is a run seed of a committed study's preset."""
    from sdbc_evolution.study.plan import study_plan

    configs = Path(__file__).resolve().parents[3] / "configs" / "study"
    earlier = ("local", "local_kinematic", "local_new_tasks", "pp_pop200")
    old = {
        s.config.seed
        for name in earlier
        for s in study_plan(load_preset_file(configs / f"{name}.yaml"), tmp_path)
    }
    for name in ("paper_runs_kinematic", "pp_pop50_control"):
        preset = load_preset_file(configs / f"{name}.yaml")
        assert preset.champion_trials >= 50
        plan = study_plan(preset, tmp_path)
        seeds = {s.config.seed for s in plan}
        assert len(seeds) == len(plan) and not seeds & old, name
        champions = {seed for s in plan for seed in s.champion_seeds}
        assert len(champions) == len(plan) * preset.champion_trials
        assert not champions & (old | seeds), name
    preset = load_preset_file(configs / "paper_runs_kinematic.yaml")
    assert preset.runs == 20 and set(preset.tasks) == {
        "gate_escape",
        "resource_sharing",
        "predator_prey",
    }
    assert preset.experiment["evaluation"]["physics"] == "kinematic"
