"""Every relevance measure against its definition or its reference library, and the
weight transform (delta, smoothing, update schedule, one draw per update)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import pearsonr, spearmanr
from sdbc_evolution.relevance.measures import (
    CHANCE_SEED,
    MEASURES,
    chance_information,
    parse_relevance,
)
from sdbc_evolution.sdbc.weighting import WeightingSettings, mutual_information
from sdbc_evolution.transforms.pipeline import apply_transforms, parse_transforms
from sdbc_sim.settings import SettingsError
from sklearn.metrics import mutual_info_score

SETTINGS = WeightingSettings()


def population(n: int = 60, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Fitness, a dimension that follows it, a noisy one, a constant one, and an
    exact copy of the first."""
    rng = np.random.default_rng(seed)
    fitness = rng.random(n)
    raw = np.column_stack([fitness**2, rng.normal(size=n), np.full(n, 3.0), fitness**2])
    return raw, fitness


def relevance(name, raw, fitness, seed: int = 7) -> np.ndarray:
    return parse_relevance(name).compute(
        raw, fitness, SETTINGS, np.random.default_rng(seed)
    )


def drawn(seed: int = 7) -> int:
    """The one integer a measure draws from a generator seeded ``seed``."""
    return int(np.random.default_rng(seed).integers(2**31 - 1))


def test_mi_is_the_papers_estimate() -> None:
    raw, fitness = population()
    np.testing.assert_array_equal(
        relevance("mi", raw, fitness),
        mutual_information(raw, fitness, SETTINGS, drawn()),
    )


def test_mi_chance_subtracts_the_shuffled_estimate() -> None:
    raw, fitness = population()
    seed = drawn()
    shuffled = np.random.default_rng((CHANCE_SEED, seed)).permutation(fitness)
    chance = mutual_information(raw, shuffled, SETTINGS, seed)
    information = mutual_information(raw, fitness, SETTINGS, seed)
    np.testing.assert_array_equal(
        chance_information(raw, fitness, SETTINGS, seed), chance
    )
    got = relevance("mi_chance", raw, fitness)
    np.testing.assert_array_equal(got, np.maximum(information - chance, 0.0))
    # The noise dimension keeps nothing above chance; the signal keeps most.
    assert got[1] < 0.5 * information[1] and got[0] > 0.5 * information[0]
    several = relevance({"mi_chance": {"shuffles": 3}}, raw, fitness)
    assert several.shape == (4,)


@pytest.mark.parametrize(
    ("name", "statistic"),
    [
        ("pearson", lambda x, y: pearsonr(x, y).statistic),
        ("spearman", lambda x, y: spearmanr(x, y).statistic),
    ],
)
def test_correlations_are_scipys(name, statistic) -> None:
    raw, fitness = population()
    got = relevance(name, raw, fitness)
    expected = [abs(statistic(raw[:, k], fitness)) for k in (0, 1)]
    np.testing.assert_allclose(got[[0, 1]], expected, rtol=1e-12)
    assert got[2] == 0.0  # constant dimension
    if name == "spearman":
        assert got[0] == pytest.approx(1.0)  # x^2 is monotonic on [0, 1]


@pytest.mark.slow  # importing dcor compiles its numba code (15 s of CPU)
def test_distance_correlation_by_its_definition() -> None:
    # Szekely, Rizzo & Bakirov 2007, from double-centred distance matrices.
    raw, fitness = population(n=30)

    def centred(v: np.ndarray) -> np.ndarray:
        d = np.abs(v[:, None] - v[None, :])
        return d - d.mean(axis=0) - d.mean(axis=1)[:, None] + d.mean()

    b = centred(fitness)
    expected = []
    for k in (0, 1):
        a = centred(raw[:, k])
        dcov2 = (a * b).mean()
        expected.append(math.sqrt(dcov2 / math.sqrt((a * a).mean() * (b * b).mean())))
    got = relevance("dcor", raw, fitness)
    np.testing.assert_allclose(got[[0, 1]], expected, rtol=1e-9)
    assert got[2] == 0.0


def test_mrmr_discounts_a_copy_by_its_redundancy() -> None:
    raw, fitness = population()
    seed = drawn()
    information = mutual_information(raw, fitness, SETTINGS, seed)
    bins = [
        np.minimum(np.floor((c - c.min()) / (np.ptp(c) or 1) * 10).astype(int), 9)
        for c in raw.T
    ]
    pair = np.array(
        [[mutual_info_score(a, b) / math.log(2) for b in bins] for a in bins]
    )
    # By hand: greedy, relevance minus the mean redundancy with those chosen.
    chosen, score = [], np.zeros(4)
    left = [0, 1, 2, 3]
    while left:
        values = [
            information[k] - (np.mean(pair[k, chosen]) if chosen else 0.0) for k in left
        ]
        best = left[int(np.argmax(values))]
        score[best] = max(values)
        chosen.append(best)
        left.remove(best)
    got = relevance("mrmr", raw, fitness)
    np.testing.assert_allclose(got, np.maximum(score, 0.0), atol=1e-12)
    # The copy (dimension 3) of the most relevant one counts for much less; with
    # the summed redundancy (MIFS) for nothing.
    assert got[0] > 1.0 and got[3] < 0.5 * got[0]
    summed = relevance({"mrmr": {"redundancy": "sum"}}, raw, fitness)
    assert summed[0] == got[0] and summed[3] == 0.0


def test_every_measure_draws_one_integer() -> None:
    raw, fitness = population(n=20)
    for name in MEASURES:
        if name == "dcor":
            continue  # importing dcor compiles numba code: slow; same code path
        rng = np.random.default_rng(1)
        parse_relevance(name).compute(raw, fitness, SETTINGS, rng)
        reference = np.random.default_rng(1)
        reference.integers(2**31 - 1)
        assert rng.random() == reference.random(), name


def test_bad_declarations_name_the_part() -> None:
    with pytest.raises(SettingsError, match=r"unknown relevance measure 'mutual'"):
        parse_relevance("mutual")
    with pytest.raises(SettingsError, match=r"relevance.mrmr.redundancy"):
        parse_relevance({"mrmr": {"redundancy": "max"}})
    with pytest.raises(SettingsError, match=r"transforms.0.weight.smoothing"):
        parse_transforms([{"weight": {"smoothing": 1.5}}])
    with pytest.raises(SettingsError, match=r"weight must come after standardise"):
        parse_transforms(["weight", "standardise"])
    with pytest.raises(SettingsError, match=r"unknown transform 'scale'"):
        parse_transforms(["scale"])
    with pytest.raises(SettingsError, match=r"appears twice"):
        parse_transforms(["standardise", "standardise"])


def test_weights_update_on_schedule_and_smooth() -> None:
    raw, fitness = population()
    transforms = parse_transforms(
        [{"weight": {"relevance": "pearson", "smoothing": 0.25}}]
    )
    settings = WeightingSettings(update_every=2)
    rng = np.random.default_rng(0)
    common = (np.zeros((0, 4)), fitness)
    first = apply_transforms(transforms, raw, *common, None, 0, rng, None, settings)
    pearson = relevance("pearson", raw, fitness)
    np.testing.assert_allclose(first.weights, 0.25 + pearson)  # nothing to smooth
    np.testing.assert_allclose(first.population, raw * first.weights)
    kept = apply_transforms(
        transforms, raw[::-1], *common, first.weights, 1, rng, None, settings
    )
    np.testing.assert_array_equal(kept.weights, first.weights)  # not a generation
    assert kept.relevance is None
    other = raw.copy()
    other[:, 1] = fitness  # now dimension 1 follows fitness exactly
    updated = apply_transforms(
        transforms, other, *common, first.weights, 2, rng, None, settings
    )
    new = 0.25 + relevance("pearson", other, fitness)
    np.testing.assert_allclose(updated.weights, 0.75 * new + 0.25 * first.weights)
