"""Comparing a task's compiled rules with the array formulation kept as their
oracle: the per-trial state both leave behind."""

from __future__ import annotations

import dataclasses

import numpy as np
from sdbc_sim.task import TrialArrays


def assert_same_trials(got: TrialArrays, want: TrialArrays) -> None:
    """Every array of two per-trial states equal, the field named on failure."""
    for field in dataclasses.fields(got):
        np.testing.assert_array_equal(
            getattr(got, field.name), getattr(want, field.name), field.name
        )


def same_bits(got: np.ndarray, want: np.ndarray) -> bool:
    """Equal shapes, types and bits (-0.0 is not 0.0, a NaN equals its bits)."""
    return (
        got.shape == want.shape
        and got.dtype == want.dtype
        and got.tobytes() == want.tobytes()
    )
