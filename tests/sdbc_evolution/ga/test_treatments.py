"""The four treatments: one evaluation -> novelty, archive entries, an order."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.novelty import NoveltyConfig, novelty_scores
from sdbc_evolution.ga.rankings.nsga2 import nsga2_order
from sdbc_evolution.ga.treatments import PRESETS, TreatmentSpec, score_generation
from sdbc_evolution.run.evaluators import Evaluation
from sdbc_evolution.sdbc.standardise import StandardisationSettings, standardise
from sdbc_evolution.sdbc.weighting import WeightingSettings, mutual_information_weights

NOVELTY = NoveltyConfig(k=3, archive_probability=0.5, archive_size=10)


def evaluation(n: int = 8, seed: int = 0) -> Evaluation:
    rng = np.random.default_rng(seed)
    sdbc = rng.normal(size=(n, 4)) * [1, 10, 100, 0]  # last dimension constant
    return Evaluation(
        fitness=rng.random(n),
        trial_fitness=rng.random((n, 2)),
        behaviours={"task": rng.random((n, 3)), "sdbc": sdbc},
    )


def score(
    treatment: TreatmentSpec,
    e: Evaluation,
    archive: NoveltyArchive,
    weights=None,
    generation: int = 0,
    seed: int = 5,
    weighting: WeightingSettings | None = None,
):
    rng = np.random.default_rng(seed)
    scores = score_generation(
        treatment,
        e,
        archive,
        weights,
        generation,
        rng,
        NOVELTY,
        StandardisationSettings(),
        weighting or WeightingSettings(),
    )
    return scores, rng


def empty_archive() -> NoveltyArchive:
    return NoveltyArchive(capacity=10, probability=0.5)


def test_fit_orders_by_fitness_and_touches_nothing_else() -> None:
    e = evaluation()
    archive = empty_archive()
    scores, rng = score(PRESETS["fit"], e, archive)
    assert scores.order.tolist() == np.argsort(-e.fitness).tolist()
    assert np.isnan(scores.novelty).all() and scores.weights is None
    assert len(archive) == 0 and not scores.archived.any()
    # No draw from the GA's generator.
    assert rng.random() == np.random.default_rng(5).random()


def test_ns_ts_uses_the_task_characterisation_as_it_is() -> None:
    e = evaluation()
    archive = empty_archive()
    archive.offer(np.full((2, 3), 0.5), np.zeros(2), 0, np.random.default_rng(1))
    before = archive.behaviours.copy()
    scores, _ = score(PRESETS["ns-ts"], e, archive)
    np.testing.assert_array_equal(
        scores.novelty, novelty_scores(e.characterisation, before, NOVELTY.k)
    )
    order, front, _ = nsga2_order(np.column_stack([e.fitness, scores.novelty]))
    assert scores.order.tolist() == order.tolist()
    assert scores.front.tolist() == front.tolist()
    # The archive got raw vectors of the individuals it drew.
    added = e.characterisation[scores.archived]
    assert archive.behaviours[len(before) :].tolist() == added.tolist()


def test_ns_sd_standardises_against_population_and_archive() -> None:
    e = evaluation()
    archive = empty_archive()
    archive.offer(evaluation(seed=9).sdbc, np.zeros(8), 0, np.random.default_rng(2))
    before = archive.behaviours.copy()
    scores, _ = score(PRESETS["ns-sd"], e, archive)
    population_z, archive_z = standardise(e.sdbc, before)
    np.testing.assert_array_equal(
        scores.novelty, novelty_scores(population_z, archive_z, NOVELTY.k)
    )
    assert scores.weights is None
    # Raw vectors in the archive, not standardised ones.
    assert np.abs(archive.behaviours).max() > 3


def test_ns_sd_plus_weights_the_standardised_dimensions() -> None:
    e = evaluation()
    scores, _ = score(PRESETS["ns-sd+"], e, empty_archive())
    seed = int(np.random.default_rng(5).integers(2**31 - 1))
    weights = mutual_information_weights(e.sdbc, e.fitness, WeightingSettings(), seed)
    np.testing.assert_array_equal(scores.weights, weights)
    assert weights[3] == 0.25  # the constant dimension
    population_z, _ = standardise(e.sdbc)
    np.testing.assert_array_equal(
        scores.novelty, novelty_scores(population_z * weights, np.empty(0), NOVELTY.k)
    )


def test_ns_sd_plus_keeps_its_weights_between_updates() -> None:
    e = evaluation()
    every_3 = WeightingSettings(update_every=3)
    old = np.array([1.0, 2.0, 3.0, 4.0])
    kept, rng = score(
        PRESETS["ns-sd+"],
        e,
        empty_archive(),
        weights=old,
        generation=4,
        weighting=every_3,
    )
    np.testing.assert_array_equal(kept.weights, old)
    renewed, _ = score(
        PRESETS["ns-sd+"],
        e,
        empty_archive(),
        weights=old,
        generation=6,
        weighting=every_3,
    )
    assert not np.array_equal(renewed.weights, old)
    first, _ = score(
        PRESETS["ns-sd+"],
        e,
        empty_archive(),
        weights=None,
        generation=4,
        weighting=every_3,
    )
    assert first.weights is not None


@pytest.mark.parametrize("treatment", list(PRESETS.values()))
def test_scores_are_a_function_of_the_generator_state(
    treatment: TreatmentSpec,
) -> None:
    a, _ = score(treatment, evaluation(), empty_archive())
    b, _ = score(treatment, evaluation(), empty_archive())
    assert a.order.tolist() == b.order.tolist()
    np.testing.assert_array_equal(a.novelty, b.novelty)
