"""The trials' generators built in bulk against numpy's default_rng, one by one."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_sim.generators import trial_generators

EDGE_SEEDS = [0, 1, 2, 12345, 2**32 - 1, 2**32, 2**32 + 1, 2**63 - 1, 2**64 - 1]


def seeds_to_check() -> list[int]:
    rng = np.random.default_rng(5)
    return (
        EDGE_SEEDS
        + [int(s) for s in rng.integers(0, 2**32, 300)]
        + [int(s) for s in rng.integers(0, 2**63, 300, dtype=np.int64)]
    )


def test_generators_are_default_rngs_to_the_state() -> None:
    seeds = seeds_to_check()
    got = trial_generators(np.array(seeds, dtype=np.uint64))
    assert len(got) == len(seeds)
    for generator, seed in zip(got, seeds, strict=True):
        assert generator.bit_generator.state == (
            np.random.default_rng(seed).bit_generator.state
        ), seed


def test_generators_draw_and_spawn_as_default_rngs() -> None:
    """Their draws, and the seed sequence behind them (entropy, other state
    sizes, spawned children), are default_rng's."""
    for seed in EDGE_SEEDS:
        (got,) = trial_generators(np.array([seed], dtype=np.uint64))
        want = np.random.default_rng(seed)
        assert np.array_equal(got.random(50), want.random(50))
        assert np.array_equal(got.integers(0, 1000, 50), want.integers(0, 1000, 50))
        assert np.array_equal(got.normal(size=50), want.normal(size=50))
        got_seq = got.bit_generator.seed_seq
        want_seq = want.bit_generator.seed_seq
        assert got_seq.entropy == want_seq.entropy
        assert np.array_equal(got_seq.generate_state(3), want_seq.generate_state(3))
        for a, b in zip(got.spawn(2), want.spawn(2), strict=True):
            assert np.array_equal(a.random(10), b.random(10))


def test_int64_seeds_as_the_engine_holds_them() -> None:
    seeds = np.array([0, 7, 2**40], dtype=np.int64)
    for generator, seed in zip(trial_generators(seeds), seeds, strict=True):
        assert generator.random() == np.random.default_rng(int(seed)).random()
    assert trial_generators(np.zeros(0, dtype=np.int64)) == []


@pytest.mark.parametrize("seed", [-1, 2**64])
def test_seeds_outside_the_range_are_refused(seed: int) -> None:
    with pytest.raises(ValueError, match=r"every seed must lie in \[0, 2\^64\)"):
        trial_generators(np.array([3, seed], dtype=object))
