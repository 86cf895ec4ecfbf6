"""Aggregation of feature samples: mean ignoring NaN, final value, trial length."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sdbc_evolution.sdbc.aggregation import (
    TrialAggregator,
    aggregate_trial,
    characterisation_length,
    mean_over_trials,
)

NAN = math.nan


def test_hand_computed_trial() -> None:
    samples = np.array(
        [
            [1.0, NAN, NAN],
            [NAN, 2.0, NAN],
            [3.0, NAN, NAN],
            [NAN, NAN, NAN],
        ]
    )
    # Means over defined steps: 2, 2, never defined -> 0. Finals: the last defined
    # value (3 at step 3, 2 at step 2), 0 if never defined. Length 4.
    expected = [2.0, 2.0, 0.0, 3.0, 2.0, 0.0, 4.0]
    np.testing.assert_array_equal(aggregate_trial(samples), expected)
    aggregator = TrialAggregator(1, 3)
    for row in samples:
        aggregator.update(row[None], np.ones(1, bool))
    np.testing.assert_array_equal(aggregator.result()[0], expected)
    assert characterisation_length(3) == len(expected)


def test_inactive_trials_keep_their_values() -> None:
    aggregator = TrialAggregator(2, 1)
    aggregator.update(np.array([[1.0], [10.0]]), np.array([True, True]))
    # Trial 1 ended after one step: later values, even defined ones, do not count.
    aggregator.update(np.array([[3.0], [99.0]]), np.array([True, False]))
    np.testing.assert_array_equal(
        aggregator.result(), [[2.0, 3.0, 2.0], [10.0, 10.0, 1.0]]
    )
    np.testing.assert_array_equal(aggregator.lengths, [2, 1])


def test_update_checks_shapes() -> None:
    aggregator = TrialAggregator(2, 3)
    with pytest.raises(ValueError, match="do not fit 2 trials of 3 features"):
        aggregator.update(np.zeros((3, 2)), np.ones(2, bool))


@settings(max_examples=60, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 30), st.integers(1, 6)),
        elements=st.one_of(
            st.just(NAN), st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
        ),
    )
)
def test_streaming_equals_one_go(samples: np.ndarray) -> None:
    aggregator = TrialAggregator(1, samples.shape[1])
    for row in samples:
        aggregator.update(row[None], np.ones(1, bool))
    np.testing.assert_allclose(
        aggregator.result()[0], aggregate_trial(samples), rtol=1e-12, atol=1e-9
    )


@pytest.mark.parametrize("some", [False, True])
def test_step_totals_add_as_the_values_do_to_the_bit(some: bool) -> None:
    """update_from_totals (the extractor's compiled step), or update_trials with
    the active trials only (``some``: its step once few are left), against
    update, the numpy formulation, given total / count with NaN where the count
    is 0: sums, counts, last values and lengths to the bit, over steps with
    trials ending, counts of 0 and totals of -0.0."""
    rng = np.random.default_rng(3)
    n_features, n_trials = 5, 37
    by_totals = TrialAggregator(n_trials, n_features)
    by_values = TrialAggregator(n_trials, n_features)
    active = np.ones(n_trials, dtype=bool)
    for step in range(12):
        trials = np.flatnonzero(active) if some else np.arange(n_trials)
        count = rng.integers(0, 4, (n_features, trials.size)).astype(np.float64)
        total = np.where(count > 0, rng.normal(size=count.shape) * count, 0.0)
        total[rng.random(count.shape) < 0.1] = -0.0
        values = np.full((n_trials, n_features), NAN)
        values[trials] = np.where(count > 0, total / np.maximum(count, 1.0), NAN).T
        if some:
            by_totals.update_trials(trials, total, count)
        elif step % 2:
            # Arrays of any layout (the loop wants contiguous rows).
            by_totals.update_from_totals(
                np.asfortranarray(total), np.asfortranarray(count), active
            )
        else:
            by_totals.update_from_totals(total, count, active)
        by_values.update(values, active)
        active &= rng.random(n_trials) < 0.85
    for name in ("_sum", "_count", "_last", "_length"):
        got, want = getattr(by_totals, name), getattr(by_values, name)
        assert np.array_equal(got.view(np.int64), want.view(np.int64)), name


def test_mean_over_trials_is_per_controller() -> None:
    vectors = np.arange(12.0).reshape(6, 2)  # 3 controllers x 2 trials
    np.testing.assert_array_equal(
        mean_over_trials(vectors, 2), [[1.0, 2.0], [5.0, 6.0], [9.0, 10.0]]
    )
    with pytest.raises(ValueError, match="do not split into controllers of 4 trials"):
        mean_over_trials(vectors, 4)
