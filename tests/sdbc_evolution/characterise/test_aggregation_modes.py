"""Every SDBC aggregation mode against a computation of its own from stored samples
(by hand, or numpy.polyfit for the regression), dimension names included."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.sdbc.aggregation import (
    BINS_PER_FRAME,
    make_aggregator,
    mode_names,
)

NAN = np.nan


def stream(mode: str, frames: int, trials: list[np.ndarray]) -> np.ndarray:
    """Streams trials of unequal length (T_b, F) through a mode's aggregator,
    the shorter trials inactive once they have ended."""
    n_features = trials[0].shape[1]
    aggregator = make_aggregator(mode, frames, len(trials), n_features)
    for t in range(max(len(s) for s in trials)):
        active = np.array([t < len(s) for s in trials])
        values = np.array(
            [s[t] if t < len(s) else np.full(n_features, 99.0) for s in trials]
        )
        aggregator.update(values, active)
    return aggregator.result()


# Trial 0: 4 steps; feature 0 undefined at steps 2 and 4, feature 1 always defined.
# Trial 1: 2 steps; feature 1 never defined.
TRIALS = [
    np.array([[1.0, 10.0], [NAN, 20.0], [3.0, 40.0], [NAN, 30.0]]),
    np.array([[5.0, NAN], [7.0, NAN]]),
]


def test_mean_final_mean_and_final_by_hand() -> None:
    got = stream("mean+final", 0, TRIALS)
    np.testing.assert_array_equal(
        got, [[2.0, 25.0, 3.0, 30.0, 4.0], [6.0, 0.0, 7.0, 0.0, 2.0]]
    )
    np.testing.assert_array_equal(
        stream("mean", 0, TRIALS), [[2.0, 25.0, 4.0], [6.0, 0.0, 2.0]]
    )
    np.testing.assert_array_equal(
        stream("final", 0, TRIALS), [[3.0, 30.0, 4.0], [7.0, 0.0, 2.0]]
    )
    features = ("Agent energy level", "Agent linear speed")
    assert mode_names("mean", 0, features) == (
        "Agent energy level (M)",
        "Agent linear speed (M)",
        "Simulation length",
    )
    assert mode_names("final", 0, features)[1] == "Agent linear speed (F)"


def test_regression_matches_polyfit() -> None:
    got = stream("regression", 0, TRIALS)
    # Trial 0, feature 0: points (1, 1), (3, 3): slope 1, intercept 0.
    slope1, intercept1 = np.polyfit([1, 2, 3, 4], [10, 20, 40, 30], 1)
    slope2, intercept2 = np.polyfit([1, 2], [5, 7], 1)
    np.testing.assert_allclose(
        got,
        [
            [0.0, intercept1, 1.0, slope1, 4.0],
            [intercept2, 0.0, slope2, 0.0, 2.0],
        ],
        atol=1e-12,
    )
    # One defined step: slope 0, that value as intercept.
    single = stream("regression", 0, [np.array([[NAN], [6.0], [NAN]])])
    np.testing.assert_array_equal(single, [[6.0, 0.0, 3.0]])
    assert mode_names("regression", 0, ("Agent linear speed",)) == (
        "Agent linear speed (intercept)",
        "Agent linear speed (slope)",
        "Simulation length",
    )


def windows(samples: np.ndarray, frames: int) -> np.ndarray:
    """Per-window means, window k holding steps t with floor((t-1) N / T) = k."""
    n_steps = samples.shape[0]
    out = []
    for k in range(frames):
        rows = [t for t in range(n_steps) if t * frames // n_steps == k]
        block = samples[rows]
        means = [
            np.nanmean(column) if np.isfinite(column).any() else 0.0
            for column in block.T
        ]
        out.extend(means)
    return np.array(out + [float(n_steps)])


def test_frames_by_hand_on_a_short_trial() -> None:
    got = stream("frames", 2, TRIALS)
    # Trial 0, windows {1, 2} and {3, 4}; trial 1, windows {1} and {2}.
    np.testing.assert_array_equal(
        got, [[1.0, 15.0, 3.0, 35.0, 4.0], [5.0, 0.0, 7.0, 0.0, 2.0]]
    )
    assert mode_names("frames", 5, ("Agent energy level",))[2] == (
        "Agent energy level (frame 3/5)"
    )
    assert len(mode_names("frames", 5, ("a", "b"))) == 11


@pytest.mark.parametrize("length", [5, 31, 32, 64, 256, 512])
def test_frames_exact_when_window_edges_fall_on_bin_edges(length: int) -> None:
    # 2 frames: N x 16 = 32 bins; the window edge at T / 2 is a bin edge whenever
    # T <= 32 or T / 2 is a multiple of the bin width.
    rng = np.random.default_rng(length)
    samples = rng.normal(size=(length, 3))
    samples[rng.random(samples.shape) < 0.2] = NAN
    other = rng.normal(size=(min(length, 32) - 1, 3))  # a shorter trial beside it
    got = stream("frames", 2, [samples, other])
    np.testing.assert_allclose(got[0], windows(samples, 2), rtol=1e-12)
    np.testing.assert_allclose(got[1], windows(other, 2), rtol=1e-12)


def test_frames_edge_off_by_less_than_one_bin_otherwise() -> None:
    length, frames = 200, 3
    rng = np.random.default_rng(1)
    samples = rng.normal(size=(length, 1))
    got = stream("frames", frames, [samples])[0]
    width = 8  # 48 bins of 1, 2, 4, 8 steps: 48 x 8 = 384 >= 200
    assert frames * BINS_PER_FRAME * width >= length
    # Each step goes to the window of its bin's first step.
    window = [((t // width) * width) * frames // length for t in range(length)]
    expected = [samples[np.array(window) == k, 0].mean() for k in range(frames)]
    np.testing.assert_allclose(got[:frames], expected, rtol=1e-12)
    assert not np.allclose(got[:frames], windows(samples, frames)[:frames])
