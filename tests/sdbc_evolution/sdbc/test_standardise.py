"""Standardisation against the population plus the archive."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.standardise import (
    Standardisation,
    StandardisationSettings,
    standardise,
)


def test_hand_computed_z_scores() -> None:
    population = np.array([[0.0, 5.0, 1.0], [2.0, 5.0, 2.0]])
    archive = np.array([[4.0, 5.0, 3.0], [6.0, 5.0, 100.0]])
    # Column 0 pooled: 0, 2, 4, 6 -> mean 3, sample SD sqrt(20/3).
    # Column 1 is constant: SD 0 read as 1, so it becomes 0.
    # Column 2: the outlier 100 is clipped to +3.
    pop_z, arch_z = standardise(population, archive)
    sd0 = math.sqrt(20.0 / 3.0)
    np.testing.assert_allclose(pop_z[:, 0], [-3.0 / sd0, -1.0 / sd0])
    np.testing.assert_allclose(arch_z[:, 0], [1.0 / sd0, 3.0 / sd0])
    np.testing.assert_array_equal(pop_z[:, 1], 0.0)
    np.testing.assert_array_equal(arch_z[:, 1], 0.0)
    col2 = np.array([1.0, 2.0, 3.0, 100.0])
    z2 = (col2 - col2.mean()) / col2.std(ddof=1)
    np.testing.assert_allclose(np.r_[pop_z[:, 2], arch_z[:, 2]], np.clip(z2, -3, 3))
    assert np.abs(np.r_[pop_z, arch_z]).max() <= 3.0


def test_population_sd_option_and_clip_setting() -> None:
    population = np.array([[0.0], [10.0]])
    pop_z, arch_z = standardise(population, None, StandardisationSettings(ddof=0))
    np.testing.assert_allclose(pop_z[:, 0], [-1.0, 1.0])
    assert arch_z.shape == (0, 1)
    pop_z, _ = standardise(population, None, StandardisationSettings(clip=0.5))
    np.testing.assert_allclose(pop_z[:, 0], [-0.5, 0.5])


def test_a_single_vector_is_centred() -> None:
    coefficients = Standardisation.fit(np.array([[3.0, 4.0]]))
    np.testing.assert_array_equal(coefficients.scale, [1.0, 1.0])
    np.testing.assert_array_equal(
        coefficients.apply(np.array([[3.0, 5.0]])), [[0.0, 1.0]]
    )


@pytest.mark.parametrize(
    ("population", "archive", "message"),
    [
        (np.array([[0.0, math.nan]]), None, "population row 0 holds NaN"),
        (np.zeros((2, 3)), np.zeros((1, 2)), "archive have 2 dimensions, expected 3"),
        (np.zeros((0, 3)), None, "population is empty"),
        (np.zeros(3), None, r"must be \(n, D\)"),
        (np.zeros((2, 2)), np.array([[0.0, math.inf]]), "archive row 0 holds NaN"),
    ],
)
def test_bad_input_is_named(population, archive, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        standardise(population, archive)


@pytest.mark.parametrize(("clip", "ddof"), [(0.0, 1), (math.inf, 1), (3.0, 2)])
def test_bad_settings_are_named(clip: float, ddof: int) -> None:
    with pytest.raises(ValueError, match="^clip: " if ddof == 1 else "^ddof: "):
        StandardisationSettings(clip=clip, ddof=ddof)
