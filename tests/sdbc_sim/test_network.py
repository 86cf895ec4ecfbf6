"""The controller network: genome layout, arithmetic and genome checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_sim.network import NetworkShape, TeamNetworks, check_genomes, forward

from sdbc_sim import compiled


def sigma(a: float) -> float:
    return 1.0 / (1.0 + math.exp(-a))


def test_genome_layout_by_hand() -> None:
    shape = NetworkShape(2, 2, 1)
    assert shape.genome_length == 9
    # Hidden rows [w_j0, w_j1, b_j], then the output row [v_0, v_1, c].
    genome = np.array([1.0, 2.0, 0.5, -1.0, 0.0, 0.0, 3.0, -2.0, 0.25])
    h0, h1 = sigma(0.5 - 2.0 + 0.5), sigma(-0.5)
    expected = sigma(3.0 * h0 - 2.0 * h1 + 0.25)
    out = forward(genome, shape, np.array([[0.5, -1.0]]))
    assert out.shape == (1, 1)
    assert out[0, 0] == pytest.approx(expected, abs=1e-15)


def test_papers_network_sizes() -> None:
    assert NetworkShape(11, 7, 3).genome_length == 108
    assert NetworkShape(8, 6, 3).genome_length == 75
    assert NetworkShape(6, 5, 2).genome_length == 47


def test_a_team_computes_the_same_alone_and_in_a_batch() -> None:
    shape = NetworkShape(11, 7, 3)
    rng = np.random.default_rng(0)
    genomes = rng.uniform(-1, 1, (50, shape.genome_length))
    x = rng.uniform(-1, 1, (50, 4, 11))
    batch = TeamNetworks(shape, genomes).forward(x)
    for b in (0, 17, 49):
        assert np.array_equal(forward(genomes[b], shape, x[b]), batch[b])
    nets = TeamNetworks(shape, genomes)
    nets.take(np.array([17, 3]))
    assert np.array_equal(nets.forward(x[[17, 3]]), batch[[17, 3]])
    assert np.all((batch > 0) & (batch < 1))


def test_bad_genomes_are_named() -> None:
    shape = NetworkShape(2, 2, 1)
    with pytest.raises(ValueError, match="length 8 does not match .* needs 9"):
        check_genomes(np.zeros((1, 8)), shape)
    with pytest.raises(
        ValueError, match=r"NaN or infinite weights in genome\(s\) \[1\]"
    ):
        check_genomes(np.array([np.zeros(9), np.full(9, np.nan)]), shape)
    with pytest.raises(ValueError, match="n_hidden must be >= 1"):
        NetworkShape(2, 0, 1)


@pytest.mark.parametrize(
    ("n_in", "n_hid", "n_out", "robots", "trials"),
    [
        (1, 1, 1, 1, 1),
        (7, 5, 2, 3, 4),
        (8, 4, 2, 2, 5),
        (11, 7, 3, 4, 33),
        (13, 10, 2, 4, 257),
    ],
)
def test_the_compiled_sums_equal_the_numpy_form_to_the_bit(
    n_in: int, n_hid: int, n_out: int, robots: int, trials: int, monkeypatch
) -> None:
    """A physics process (numba loaded) and a controller node (numpy) compute the
    same outputs."""
    rng = np.random.default_rng(n_in)
    shape = NetworkShape(n_in, n_hid, n_out)
    genomes = rng.uniform(-10.0, 10.0, (trials, shape.genome_length))
    x = rng.uniform(-1.0, 1.0, (trials, robots, n_in))
    x[0, 0, 0] = np.nan
    compiled.load()
    loops = TeamNetworks(shape, genomes).forward(x)
    monkeypatch.setattr(compiled, "_loaded", False)
    plain = TeamNetworks(shape, genomes).forward(x)
    assert np.array_equal(loops.view(np.int64), plain.view(np.int64))
