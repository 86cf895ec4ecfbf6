"""The novelty metric on hand-worked examples."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.ga.novelty import novelty_scores


def test_mean_distance_to_k_nearest_among_population_and_archive() -> None:
    population = np.array([[0.0], [1.0], [3.0]])
    archive = np.array([[10.0], [0.5]])
    # 0: others 1, 3, 10, 0.5 -> nearest two 0.5, 1 -> 0.75
    # 1: 1, 2, 9, 0.5 -> 0.5, 1 -> 0.75
    # 3: 3, 2, 7, 2.5 -> 2, 2.5 -> 2.25
    assert novelty_scores(population, archive, k=2).tolist() == [0.75, 0.75, 2.25]


def test_an_individual_is_not_its_own_neighbour_but_its_clone_is() -> None:
    population = np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 4.0]])
    scores = novelty_scores(population, np.zeros((0, 2)), k=1)
    assert scores.tolist() == [0.0, 0.0, 5.0]


def test_fewer_neighbours_than_k_uses_all_of_them() -> None:
    population = np.array([[0.0], [2.0]])
    assert novelty_scores(population, np.empty(0), k=15).tolist() == [2.0, 2.0]
    assert novelty_scores(np.array([[1.0]]), np.empty(0), k=3).tolist() == [0.0]


def test_bad_input_is_rejected() -> None:
    with pytest.raises(ValueError, match="NaN"):
        novelty_scores(np.array([[np.nan]]), np.empty(0), k=1)
    with pytest.raises(ValueError, match="archive"):
        novelty_scores(np.zeros((2, 3)), np.zeros((2, 2)), k=1)
    with pytest.raises(ValueError, match="k must"):
        novelty_scores(np.zeros((2, 3)), np.empty(0), k=0)
