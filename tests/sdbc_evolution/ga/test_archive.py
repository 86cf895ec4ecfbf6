"""The archive policy: add with probability p, replace a random entry when full."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.ga.archive import NoveltyArchive


def test_fills_then_replaces_random_entries_in_draw_order() -> None:
    archive = NoveltyArchive(capacity=3, probability=0.5)
    behaviours = np.arange(12.0).reshape(6, 2)
    fitness = np.arange(6.0) / 10
    added = archive.offer(
        behaviours, fitness, generation=4, rng=np.random.default_rng(25)
    )
    # Replay the policy by hand with the same generator.
    rng = np.random.default_rng(25)
    expected_added = rng.random(6) < 0.5
    assert added.tolist() == expected_added.tolist()
    chosen = np.flatnonzero(expected_added)
    assert chosen.size > 3  # this seed fills the archive and replaces
    slots = list(chosen[:3])
    for i in chosen[3:]:
        slots[int(rng.integers(3))] = i
    assert archive.behaviours.tolist() == behaviours[slots].tolist()
    assert archive.fitness.tolist() == fitness[slots].tolist()
    assert archive.generation.tolist() == [4, 4, 4]


def test_probability_one_keeps_the_first_entries_until_full() -> None:
    archive = NoveltyArchive(capacity=10, probability=1.0)
    archive.offer(np.ones((4, 3)), np.zeros(4), 0, np.random.default_rng(0))
    archive.offer(2 * np.ones((4, 3)), np.ones(4), 1, np.random.default_rng(0))
    assert len(archive) == 8
    assert archive.generation.tolist() == [0] * 4 + [1] * 4


def test_probability_zero_and_capacity_zero_add_nothing() -> None:
    for capacity, probability in ((5, 0.0), (0, 1.0)):
        archive = NoveltyArchive(capacity=capacity, probability=probability)
        added = archive.offer(np.ones((4, 3)), np.zeros(4), 0, np.random.default_rng(0))
        assert not added.any() and len(archive) == 0


def test_addition_rate_is_the_probability() -> None:
    archive = NoveltyArchive(capacity=100_000, probability=0.03)
    added = archive.offer(
        np.zeros((100_000, 1)), np.zeros(100_000), 0, np.random.default_rng(1)
    )
    # Binomial(1e5, 0.03): SD 54; 5 SD either side.
    assert abs(added.sum() - 3000) < 270
    assert len(archive) == added.sum()


def test_bad_settings_and_shapes_are_rejected() -> None:
    with pytest.raises(ValueError, match="probability"):
        NoveltyArchive(capacity=3, probability=1.5)
    with pytest.raises(ValueError, match="capacity"):
        NoveltyArchive(capacity=-1, probability=0.5)
    archive = NoveltyArchive(capacity=3, probability=1.0)
    archive.offer(np.ones((1, 3)), np.zeros(1), 0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="dimensions"):
        archive.offer(np.ones((1, 2)), np.zeros(1), 0, np.random.default_rng(0))
