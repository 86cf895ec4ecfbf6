"""NS-SD+ weights: delta + I(F; k) in bits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.weighting import (
    FeatureWeighting,
    WeightingSettings,
    equal_width_classes,
    kmeans_classes,
    mutual_information,
    mutual_information_weights,
)


@pytest.mark.parametrize("discretisation", ["equal_width", "kmeans"])
def test_the_feature_fitness_depends_on_gets_the_largest_weight(discretisation) -> None:
    rng = np.random.default_rng(11)
    raw = rng.uniform(size=(200, 21))
    fitness = np.sin(3.0 * raw[:, 7]) + 0.05 * rng.normal(size=200)
    settings = WeightingSettings(feature_discretisation=discretisation)
    weights = mutual_information_weights(raw, fitness, settings, seed=5)
    assert weights.shape == (21,)
    assert int(np.argmax(weights)) == 7
    assert (weights >= settings.delta).all()
    # Well clear of the noise floor of the plug-in estimate.
    assert (
        weights[7] - settings.delta > 2.0 * np.delete(weights - settings.delta, 7).max()
    )


def test_hand_computed_bits() -> None:
    # Fitness takes two values, one per half; feature 0 splits the halves exactly
    # (1 bit), feature 1 is independent of fitness (0 bits), feature 2 is constant.
    fitness = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0])
    raw = np.array(
        [
            [0.0, 0.0, 7.0],
            [0.1, 1.0, 7.0],
            [0.2, 0.0, 7.0],
            [0.3, 1.0, 7.0],
            [0.9, 0.0, 7.0],
            [1.0, 1.0, 7.0],
            [0.9, 0.0, 7.0],
            [1.0, 1.0, 7.0],
        ]
    )
    settings = WeightingSettings(feature_bins=2)
    information = mutual_information(raw, fitness, settings)
    np.testing.assert_allclose(information, [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(
        mutual_information_weights(raw, fitness, settings), [1.25, 0.25, 0.25]
    )


def test_discretisers() -> None:
    np.testing.assert_array_equal(
        equal_width_classes(np.array([0.0, 0.49, 0.5, 1.0]), 2), [0, 0, 1, 1]
    )
    np.testing.assert_array_equal(equal_width_classes(np.full(3, 2.0), 10), [0, 0, 0])
    # Few distinct values: each is its own cluster.
    np.testing.assert_array_equal(
        kmeans_classes(np.array([3.0, 1.0, 3.0]), 10, 0, 1), [1, 0, 1]
    )
    # Three clear groups and three clusters.
    values = np.array([0.0, 0.1, 0.2, 5.0, 5.1, 9.0, 9.2, 9.1])
    labels = kmeans_classes(values, 3, 0, 10)
    assert len(set(labels[:3])) == len(set(labels[3:5])) == len(set(labels[5:])) == 1
    assert len(set(labels)) == 3


def test_seeded_weights_are_reproducible() -> None:
    rng = np.random.default_rng(2)
    raw = rng.normal(size=(100, 5))
    fitness = raw[:, 0] + rng.normal(size=100)
    a = mutual_information_weights(raw, fitness, seed=np.random.default_rng(9))
    b = mutual_information_weights(raw, fitness, seed=np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)


def test_weights_are_recomputed_every_n_generations() -> None:
    rng = np.random.default_rng(3)
    weighting = FeatureWeighting(WeightingSettings(update_every=2))
    raw0 = rng.uniform(size=(100, 3))
    raw1 = rng.uniform(size=(100, 3))
    w0 = weighting.update(0, raw0, raw0[:, 0], seed=1).copy()
    # Generation 1 keeps generation 0's weights although fitness now follows x2.
    np.testing.assert_array_equal(weighting.update(1, raw1, raw1[:, 2], seed=1), w0)
    w2 = weighting.update(2, raw1, raw1[:, 2], seed=1)
    assert int(np.argmax(w0)) == 0
    assert int(np.argmax(w2)) == 2


@pytest.mark.parametrize(
    ("raw", "fitness", "message"),
    [
        (np.zeros((3, 2)), np.zeros(4), r"fitness has shape \(4,\), expected \(3,\)"),
        (np.array([[0.0, math.nan]]), np.zeros(1), "raw characterisations hold NaN"),
        (np.zeros((2, 2)), np.array([0.0, math.inf]), "fitness holds NaN"),
        (np.zeros(3), np.zeros(3), r"must be \(n, D\)"),
    ],
)
def test_bad_input_is_named(raw, fitness, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        mutual_information_weights(raw, fitness)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("delta", -0.1),
        ("fitness_clusters", 1),
        ("feature_bins", 0),
        ("feature_discretisation", "quantile"),
        ("update_every", 0),
    ],
)
def test_bad_settings_are_named(field: str, value) -> None:
    with pytest.raises(ValueError, match=field):
        WeightingSettings(**{field: value})
