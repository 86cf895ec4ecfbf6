"""NSGA-II fronts and crowding distances against hand-worked examples."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sdbc_evolution.ga.rankings.nsga2 import (
    crowding_distance,
    domination_matrix,
    non_dominated_fronts,
    normalised_fitness_in_front,
    nsga2_order,
    positions,
)

# (fitness, novelty), both maximised. Worked by hand:
#   front 0: 0 (1,5), 1 (2,4), 2 (3,3), 6 (4,0)  -- nobody beats them
#   front 1: 4 (2,2) (beaten by 1 and 2)
#   front 2: 3 (1,1) (beaten by 4 too)
#   front 3: 5 (0,0) (beaten by 3 as well)
EXAMPLE = np.array(
    [[1, 5], [2, 4], [3, 3], [1, 1], [2, 2], [0, 0], [4, 0]], dtype=float
)


def test_fronts_of_the_worked_example() -> None:
    assert non_dominated_fronts(EXAMPLE).tolist() == [0, 0, 0, 2, 1, 3, 0]


def test_crowding_of_the_worked_example() -> None:
    fronts = non_dominated_fronts(EXAMPLE)
    cd = crowding_distance(EXAMPLE, fronts)
    # Front 0, sorted on fitness: 0, 1, 2, 6 (span 3); on novelty: 6, 2, 1, 0 (span 5).
    # 1: (3 - 1)/3 + (5 - 3)/5 = 16/15;  2: (4 - 2)/3 + (4 - 0)/5 = 22/15.
    assert cd[1] == pytest.approx(16 / 15)
    assert cd[2] == pytest.approx(22 / 15)
    # Extremes of each objective, and fronts of one or two, are infinitely far.
    assert np.isinf(cd[[0, 6, 3, 4, 5]]).all()


def test_order_of_the_worked_example() -> None:
    order, fronts, key = nsga2_order(EXAMPLE)
    # Front 0 first: the two infinite ones by index (0, 6), then 2 (22/15), 1 (16/15).
    assert order.tolist() == [0, 6, 2, 1, 4, 3, 5]
    assert positions(order).tolist() == [0, 3, 2, 5, 4, 6, 1]
    assert fronts.tolist() == [0, 0, 0, 2, 1, 3, 0]


def test_authors_tie_break_orders_a_front_by_fitness() -> None:
    order, _, key = nsga2_order(EXAMPLE, tie_break="fitness")
    # Front 0 fitness 1, 2, 3, 4 -> 0, 1/3, 2/3, 1; fronts of one get 0.5.
    assert key[[0, 1, 2, 6]] == pytest.approx([0, 1 / 3, 2 / 3, 1])
    assert key[5] == 0.5
    assert key[[3, 4]].tolist() == [0.5, 0.5]
    assert order.tolist() == [6, 2, 1, 0, 4, 3, 5]


def test_equal_points_share_a_front_and_constant_objectives_add_nothing() -> None:
    obj = np.array([[1.0, 2.0], [1.0, 2.0], [1.0, 3.0], [1.0, 1.0], [1.0, 1.5]])
    assert non_dominated_fronts(obj).tolist() == [1, 1, 0, 3, 2]
    # Equal fitness: novelty alone decides domination.
    tied = np.array([[2.0, 1.0], [2.0, 2.0], [2.0, 3.0], [2.0, 4.0]])
    assert non_dominated_fronts(tied).tolist() == [3, 2, 1, 0]
    flat = np.array([[1.0, 4.0], [2.0, 3.0], [3.0, 2.0], [4.0, 1.0], [2.5, 2.5]])
    cd = crowding_distance(flat, non_dominated_fronts(flat))
    # Sorted on fitness: 1, 2, 2.5, 3, 4 (span 3); on novelty: 1, 2, 2.5, 3, 4.
    # Point 4 (2.5, 2.5): (3 - 2)/3 + (3 - 2)/3 = 2/3.
    assert cd[4] == pytest.approx(2 / 3)


def test_domination_is_strict() -> None:
    dom = domination_matrix(np.array([[1.0, 1.0], [1.0, 1.0], [1.0, 0.0]]))
    assert not dom[0, 1] and not dom[1, 0]
    assert dom[0, 2] and dom[1, 2] and not dom[2, 0]


def test_bad_objectives_are_rejected() -> None:
    with pytest.raises(ValueError, match="NaN"):
        non_dominated_fronts(np.array([[1.0, np.nan]]))
    with pytest.raises(ValueError, match=r"\(N, M\)"):
        non_dominated_fronts(np.zeros(3))
    with pytest.raises(ValueError, match="tie_break"):
        nsga2_order(EXAMPLE, tie_break="random")


def test_normalised_fitness_of_a_constant_front_is_a_half() -> None:
    out = normalised_fitness_in_front(np.array([3.0, 3.0, 1.0]), np.array([0, 0, 1]))
    assert out.tolist() == [0.5, 0.5, 0.5]


@settings(max_examples=60, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 30), st.just(2)),
        elements=st.integers(0, 6).map(float),
    )
)
def test_fronts_are_the_definition(obj: np.ndarray) -> None:
    fronts = non_dominated_fronts(obj)
    dom = domination_matrix(obj)
    for b in range(obj.shape[0]):
        dominators = np.flatnonzero(dom[:, b])
        # Front of b = 1 + the deepest front of anything that dominates it.
        expected = 0 if dominators.size == 0 else fronts[dominators].max() + 1
        assert fronts[b] == expected
    order, _, _ = nsga2_order(obj)
    assert sorted(order.tolist()) == list(range(obj.shape[0]))
    assert (np.diff(fronts[order]) >= 0).all()
