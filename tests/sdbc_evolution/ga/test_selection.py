"""Tournament selection, elitism and the Fit treatment's order."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.ga.selection import elites, fitness_order, tournament_selection


class ScriptedIntegers:
    def __init__(self, block: np.ndarray) -> None:
        self.block = np.asarray(block)

    def integers(self, low: int, high: int, size: tuple[int, int]) -> np.ndarray:
        assert size == self.block.shape and low == 0 and (self.block < high).all()
        return self.block


def test_the_best_ranked_contestant_wins() -> None:
    positions = np.array([3, 0, 4, 1, 2])  # individual 1 is best, 2 worst
    contestants = np.array([[0, 2, 4], [2, 2, 2], [3, 1, 0], [4, 0, 2]])
    winners = tournament_selection(positions, 4, 3, ScriptedIntegers(contestants))
    assert winners.tolist() == [4, 2, 1, 4]


def test_tournament_pressure_grows_with_size() -> None:
    positions = np.arange(200)
    rng = np.random.default_rng(0)
    one = tournament_selection(positions, 20_000, 1, rng)
    five = tournament_selection(positions, 20_000, 5, rng)
    # Size 1 is uniform (mean position 99.5); size 5 picks the minimum of 5 uniform
    # draws, mean about 199/6 = 33.2.
    assert abs(one.mean() - 99.5) < 2.5
    assert abs(five.mean() - 33.2) < 1.5


def test_elites_are_the_head_of_the_order() -> None:
    assert elites(np.array([4, 2, 0, 1, 3]), 2).tolist() == [4, 2]
    assert elites(np.array([4, 2, 0]), 0).tolist() == []
    with pytest.raises(ValueError, match="elites"):
        elites(np.array([1, 0]), 3)


def test_fitness_order_is_descending_with_ties_by_index() -> None:
    assert fitness_order(np.array([0.2, 0.9, 0.2, 0.5])).tolist() == [1, 3, 0, 2]
    with pytest.raises(ValueError, match="NaN"):
        fitness_order(np.array([0.1, np.nan]))


def test_bad_tournaments_are_rejected() -> None:
    with pytest.raises(ValueError, match="tournament size"):
        tournament_selection(np.arange(3), 2, 0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="empty"):
        tournament_selection(np.arange(0), 2, 2, np.random.default_rng(0))
