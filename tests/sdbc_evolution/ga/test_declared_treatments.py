"""Declared treatments: the paper's four as presets, declarations refused naming the
part, a declared treatment from a YAML file through sdbc-evolve, and stop + resume
equal to a straight run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.novelty import NoveltyConfig
from sdbc_evolution.ga.treatments import (
    PRESET_DECLARATIONS,
    PRESETS,
    parse_treatment,
    score_generation,
)
from sdbc_evolution.run.cli import main
from sdbc_evolution.run.config import (
    ConfigError,
    config_from_dict,
    dump_config,
    load_config,
)
from sdbc_evolution.run.evaluators import Evaluation
from sdbc_evolution.run.results import TIME_COLUMNS, read_generations
from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings

DECLARED = {
    "name": "nslc-frames-chance",
    "characterisation": {"sdbc": {"aggregation": {"frames": 3}}},
    "transforms": ["standardise", {"weight": {"relevance": "mi_chance"}}],
    "ranking": {"nslc": {"k": 4}},
}


@pytest.mark.parametrize("name", list(PRESET_DECLARATIONS))
def test_presets_are_their_declarations(name: str) -> None:
    declared = parse_treatment({"name": name, **PRESET_DECLARATIONS[name]})
    assert declared == PRESETS[name] and declared.is_paper
    assert parse_treatment(name) is PRESETS[name]
    config = config_from_dict({"treatment": declared})
    assert yaml.safe_load(dump_config(config))["treatment"] == name


def test_a_declaration_round_trips_through_the_configuration() -> None:
    config = config_from_dict({"treatment": DECLARED})
    again = config_from_dict(yaml.safe_load(dump_config(config)))
    assert again == config and again.treatment.name == "nslc-frames-chance"
    assert again.treatment.directory == "nslc-frames-chance"
    assert parse_treatment(
        {"name": "a+b", **PRESET_DECLARATIONS["ns-sd"]}
    ).directory == ("a-plusb")


@pytest.mark.parametrize(
    ("declaration", "message"),
    [
        (
            {"name": "x", "ranking": "nsga2"},
            r"treatment.ranking: 'nsga2' scores novelty",
        ),
        (
            {"name": "x", "characterisation": "sdbc", "ranking": "fitness"},
            r"treatment.ranking: 'fitness' ignores novelty",
        ),
        (
            {"name": "x", "transforms": ["standardise"], "ranking": "fitness"},
            r"transforms need a characterisation",
        ),
        (
            {"name": "ns-sd", "characterisation": "task", "ranking": "nsga2"},
            r"the name of a paper treatment",
        ),
        ({"name": "a b", "characterisation": "task"}, r"treatment.name: 'a b'"),
        ({"characterisation": "task"}, r"treatment.name: a declared treatment needs"),
        ({"name": "x", "ranks": "nsga2"}, r"unknown key\(s\) \['ranks'\]"),
        (
            {"name": "x", "characterisation": "sdbc", "ranking": "nsga3"},
            r"treatment.ranking: unknown ranking 'nsga3'",
        ),
        (
            {"name": "x", "characterisation": {"sdbc": {"aggregation": "max"}}},
            r"treatment.characterisation.sdbc",
        ),
        (
            {"name": "x", "characterisation": "sdbc", "transforms": [{"weight": 1}]},
            r"treatment.transforms.0.weight",
        ),
        ("ns-xx", r"'ns-xx' is not a preset"),
    ],
)
def test_bad_declarations_name_the_part(declaration, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        config_from_dict({"treatment": declaration})


def test_a_declared_mi_weighting_scores_as_ns_sd_plus() -> None:
    rng = np.random.default_rng(2)
    evaluation = Evaluation(
        fitness=rng.random(12),
        trial_fitness=rng.random((12, 2)),
        behaviours={"task": rng.random((12, 3)), "sdbc": rng.normal(size=(12, 5))},
    )
    declared = parse_treatment(
        {
            "name": "mine",
            "characterisation": "sdbc",
            "transforms": ["standardise", {"weight": {"relevance": "mi"}}],
            "ranking": "nsga2",
        }
    )
    results = []
    for treatment in (PRESETS["ns-sd+"], declared):
        archive = NoveltyArchive(capacity=5, probability=0.5)
        scores = score_generation(
            treatment,
            evaluation,
            archive,
            None,
            0,
            np.random.default_rng(9),
            NoveltyConfig(k=3),
            StandardisationSettings(),
            WeightingSettings(),
        )
        results.append((scores, archive.behaviours))
    (a, archive_a), (b, archive_b) = results
    for field in ("order", "novelty", "front", "weights", "archived"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    np.testing.assert_array_equal(archive_a, archive_b)


TINY = """\
task: predator_prey
task_config: {max_steps: 40}
generations: 4
seed: 3
ga: {population_size: 8, elites: 1, tournament_size: 2}
novelty: {k: 3, archive_probability: 0.3}
evaluation: {trials: 2, reevaluation_trials: 0}
"""


def same_run(a: Path, b: Path) -> None:
    ga, gb = read_generations(a), read_generations(b)
    assert ga.keys() == gb.keys()
    for column in ga:
        if column not in TIME_COLUMNS:
            np.testing.assert_array_equal(ga[column], gb[column], err_msg=column)
    for file in sorted((a / "individuals").glob("*.npz")):
        with np.load(file) as x, np.load(b / "individuals" / file.name) as y:
            assert x.files == y.files
            for key in x.files:
                np.testing.assert_array_equal(x[key], y[key], err_msg=key)


@pytest.mark.slow
def test_declared_treatment_from_a_file_stopped_and_resumed_equals_a_straight_run(
    tmp_path: Path,
) -> None:
    config = tmp_path / "tiny.yaml"
    config.write_text(TINY)
    treatment = tmp_path / "treatment.yaml"
    treatment.write_text(yaml.safe_dump(DECLARED))
    common = ["--no-gif", "--quiet", "--workers", "1", "--config", str(config)]
    straight, halves = tmp_path / "straight", tmp_path / "halves"
    assert main([*common, "--treatment", str(treatment), "--out", str(straight)]) == 0
    assert (
        main(
            [*common, "--treatment", str(treatment), "--out", str(halves)]
            + ["--generations", "2"]
        )
        == 0
    )
    assert (
        main(
            ["--no-gif", "--quiet", "--workers", "1", "--resume"]
            + ["--out", str(halves), "--generations", "4"]
        )
        == 0
    )
    same_run(straight, halves)
    assert load_config(straight / "config.yaml").treatment.name == DECLARED["name"]
    with np.load(straight / "individuals" / "gen_00003.npz") as data:
        assert data["behaviour"].shape == (8, len(data["behaviour_names"]))
        assert "Predators dispersion (frame 2/3)" in data["behaviour_names"]
    weights = read_generations(straight)["weight:Predators dispersion (frame 2/3)"]
    assert np.isfinite(weights).all() and (weights >= 0.25).all()


def test_an_unknown_treatment_exits_2_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--treatment", "ns-xx", "--out", str(tmp_path / "r")]) == 2
    assert "'ns-xx' is neither a paper treatment" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({**DECLARED, "ranking": "nsga3"}))
    assert main(["--treatment", str(bad), "--out", str(tmp_path / "r")]) == 2
    assert "unknown ranking 'nsga3'" in capsys.readouterr().err
