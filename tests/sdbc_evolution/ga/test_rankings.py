"""Every ranking against a small computation by hand; bad declarations refused."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.ga.rankings import RankingContext, parse_ranking
from sdbc_evolution.ga.rankings.nsga2 import nsga2_order
from sdbc_evolution.ga.rankings.others import local_competition
from sdbc_sim.settings import SettingsError

FITNESS = np.array([0.2, 0.9, 0.5, 0.9, 0.1])
NOVELTY = np.array([3.0, 1.0, 2.0, 0.5, 4.0])


def rank(declaration, fitness=FITNESS, novelty=NOVELTY, **kwargs):
    defaults = {"population": None, "archive": None, "archive_fitness": None}
    defaults.update(kwargs)
    context = RankingContext(
        fitness,
        novelty,
        defaults["population"],
        defaults["archive"],
        defaults["archive_fitness"],
        k=2,
        tie_break="crowding",
        rng=np.random.default_rng(0),
    )
    order, front = parse_ranking(declaration).rank(context)
    return order.tolist(), front.tolist()


def test_fitness_and_novelty_alone() -> None:
    assert rank("fitness") == ([1, 3, 2, 0, 4], [0] * 5)  # tie 1, 3 by index
    assert rank("novelty") == ([4, 0, 2, 1, 3], [0] * 5)


def test_nsga2_is_the_papers() -> None:
    order, front, _ = nsga2_order(np.column_stack([FITNESS, NOVELTY]))
    assert rank("nsga2") == (order.tolist(), front.tolist())


def test_scalarised_by_hand() -> None:
    # Normalised fitness [0.125, 1, 0.5, 1, 0], novelty [0.714, 0.143, 0.429, 0, 1].
    # w = 0.5: [0.420, 0.571, 0.464, 0.5, 0.5] -> 1, 3, 4, 2, 0 (3 before 4: index).
    assert rank({"scalarised": {"weight": 0.5}})[0] == [1, 3, 4, 2, 0]
    assert rank({"scalarised": {"weight": 1.0}})[0] == rank("fitness")[0]
    assert rank({"scalarised": {"weight": 0.0}})[0] == rank("novelty")[0]


def test_minimal_criterion_by_hand() -> None:
    # Median fitness 0.5: individuals 1, 2, 3 meet it, by novelty 2, 1, 3; then
    # the others by fitness: 0, 4.
    assert rank("minimal_criterion") == ([2, 1, 3, 0, 4], [1, 0, 0, 0, 1])
    assert rank({"minimal_criterion": {"criterion": 0.15}})[0] == [0, 2, 1, 3, 4]


def test_local_competition_by_hand() -> None:
    # 1-D behaviours 0, 1, 2, 10, 11; an archive entry at 2.5 with fitness 0.95.
    population = np.array([[0.0], [1.0], [2.0], [10.0], [11.0]])
    archive = np.array([[2.5]])
    competition = local_competition(population, archive, FITNESS, np.array([0.95]), 2)
    # Nearest two: 0 -> {1, 2}: beats none; 1 -> {0, 2}: both; 2 -> {archive, 1}:
    # none; 3 -> {4, archive}: 4 only; 4 -> {3, archive}: none.
    np.testing.assert_array_equal(competition, [0.0, 1.0, 0.0, 0.5, 0.0])
    order, front, _ = nsga2_order(np.column_stack([NOVELTY, competition]))
    assert rank(
        "nslc",
        population=population,
        archive=archive,
        archive_fitness=np.array([0.95]),
    ) == (order.tolist(), front.tolist())


def test_bad_declarations_name_the_part() -> None:
    with pytest.raises(SettingsError, match=r"unknown ranking 'nsga3'"):
        parse_ranking("nsga3")
    with pytest.raises(SettingsError, match=r"ranking.scalarised.*weight"):
        parse_ranking({"scalarised": {"weight": 2}})
    with pytest.raises(SettingsError, match=r"ranking.nslc.*k"):
        parse_ranking({"nslc": {"k": 0}})
    with pytest.raises(SettingsError, match=r"ranking.fitness.weight: unknown key"):
        parse_ranking({"fitness": {"weight": 1}})
