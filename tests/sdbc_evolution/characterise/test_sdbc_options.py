"""SDBC options against computations of their own from recorded task states:
state deviation, relations, ignored groups; the paper's options through the general
extractor equal the paper's extractor; bad declarations are refused naming the part."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from sdbc_evolution.characterise.registry import parse
from sdbc_evolution.characterise.sdbc import (
    OptionedSdbcExtractor,
    SdbcOptions,
    sdbc_dimension_names,
)
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.features import StepFeatures
from sdbc_sim.engine import run_batch
from sdbc_sim.settings import SettingsError
from sdbc_sim.tasks import make_task


class Recorder:
    """Keeps a copy of every task state (fine for a few short trials)."""

    def start(self, description, n_trials: int) -> None:
        self.states = []

    def observe(self, state) -> None:
        self.states.append(copy.deepcopy(state))


@pytest.fixture(scope="module")
def predator_prey():
    task = make_task("predator_prey", max_steps=25)
    genomes = np.random.default_rng(3).uniform(-1, 1, (2, task.genome_length))
    seeds = np.array([[11, 12], [13, 14]], dtype=np.int64)
    recorder = Recorder()
    extractors = {
        "paper": SdbcExtractor(),
        "general": OptionedSdbcExtractor(SdbcOptions()),
        "extended": OptionedSdbcExtractor(
            SdbcOptions(state_deviation=True, relations=True)
        ),
        "no prey": OptionedSdbcExtractor(SdbcOptions(ignore_groups=("Prey",))),
    }
    run_batch(task, genomes, seeds, observers=(recorder, *extractors.values()))
    return (
        task,
        recorder.states,
        {k: e.characterisations() for k, e in extractors.items()},
    )


def mean_final(samples: np.ndarray) -> np.ndarray:
    """(T, F) -> [nanmean, last defined, T], 0 for never defined."""
    means, finals = [], []
    for column in samples.T:
        defined = np.flatnonzero(np.isfinite(column))
        means.append(column[defined].mean() if defined.size else 0.0)
        finals.append(column[defined[-1]] if defined.size else 0.0)
    return np.array(means + finals + [float(samples.shape[0])])


def test_paper_options_through_the_general_extractor_equal_the_paper_extractor(
    predator_prey,
) -> None:
    _, _, vectors = predator_prey
    np.testing.assert_allclose(vectors["general"], vectors["paper"], rtol=1e-12)


def test_deviation_and_relations_by_hand(predator_prey) -> None:
    task, states, vectors = predator_prey
    description = task.description
    names = sdbc_dimension_names(
        description, SdbcOptions(state_deviation=True, relations=True)
    )
    attributes = description.groups[0].attributes
    assert description.groups[1].attributes == attributes  # Predators, Prey
    base = StepFeatures(description)
    for trial in range(4):
        rows = []
        for state in states:
            if not state.active[trial]:
                continue
            predators, prey = state.groups[0], state.groups[1]
            here = predators.present[min(trial, predators.present.shape[0] - 1)]
            pred = predators.attributes[trial][here]
            prey_here = prey.present[min(trial, prey.present.shape[0] - 1)]
            prey_values = prey.attributes[trial][prey_here]
            deviation = [np.std(pred[:, a]) for a in range(len(attributes))]
            relation = [
                pred[:, a].mean() - prey_values[:, a].mean()
                if len(prey_values)
                else np.nan
                for a in range(len(attributes))
            ]
            rows.append(
                np.concatenate([base.values(state)[trial], deviation, relation])
            )
        expected = mean_final(np.array(rows))
        np.testing.assert_allclose(vectors["extended"][trial], expected, rtol=1e-9)
    assert "Predators linear speed deviation (M)" in names
    assert "Predators-prey x difference (F)" in names
    assert len(names) == len(expected)


def test_ignored_group_drops_every_feature_that_involves_it(predator_prey) -> None:
    task, _, vectors = predator_prey
    full = sdbc_dimension_names(task.description)
    kept = sdbc_dimension_names(task.description, SdbcOptions(ignore_groups=("Prey",)))
    assert not [n for n in kept if "rey" in n]
    assert len(kept) < len(full)
    columns = [full.index(n) for n in kept]
    np.testing.assert_allclose(
        vectors["no prey"], vectors["paper"][:, columns], rtol=1e-12
    )


def test_bad_declarations_name_the_part() -> None:
    with pytest.raises(SettingsError, match=r"characterisation.sdbc.*aggregation"):
        parse({"sdbc": {"aggregation": "median"}})
    with pytest.raises(SettingsError, match=r"frames"):
        parse({"sdbc": {"aggregation": {"frames": 0}}})
    with pytest.raises(
        SettingsError, match=r"characterisation.sdbc.colour: unknown key"
    ):
        parse({"sdbc": {"colour": 1}})
    with pytest.raises(SettingsError, match=r"unknown characterisation 'sdbd'.*sdbc"):
        parse("sdbd")
    gate = make_task("gate_escape").description
    with pytest.raises(ValueError, match=r"ignore_groups.*'Nope'"):
        sdbc_dimension_names(gate, SdbcOptions(ignore_groups=("Nope",)))
    with pytest.raises(ValueError, match=r"relations.*no state attribute shared"):
        sdbc_dimension_names(gate, SdbcOptions(relations=True))


def test_keys_name_the_options() -> None:
    assert parse("sdbc").key == "sdbc"
    assert parse({"sdbc": {}}).key == "sdbc"
    assert parse({"sdbc": {"aggregation": {"frames": 5}}}).key == (
        "sdbc{aggregation={frames=5}}"
    )
    assert parse({"sdbc": {"aggregation": "regression"}}).to_plain() == {
        "sdbc": {"aggregation": "regression"}
    }
