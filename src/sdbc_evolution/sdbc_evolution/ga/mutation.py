"""Bounded Gaussian mutation with redraws (the GA's only variation operator).

Each gene x of a genome mutates independently with probability p (0.05):

    x' = x + N(0, sigma^2),   sigma = 0.5,

and a value outside the gene bounds [low, high] = [-1, 1] is redrawn from the same
distribution around x (not clipped, which would pile genes on the bounds). As in
ECJ, which the authors used, after ``max_redraws`` out-of-bounds draws the gene
takes a uniform value in the bounds instead; with the numbers of
docs/reference-setup.md a redraw is needed at most half the time and that fallback never
happens in practice.

Draw order, all from one generator: one uniform per gene of the batch (which genes
mutate), one normal per mutating gene, then one normal per gene still out of bounds
in each redraw round, row-major; then one uniform per gene that exhausted its
redraws. The result is a function of the input and the generator state.
"""

from __future__ import annotations

import numpy as np


def gaussian_mutation(
    genomes: np.ndarray,
    rng: np.random.Generator,
    sigma: float,
    probability: float,
    low: float,
    high: float,
    max_redraws: int,
) -> np.ndarray:
    """Mutates a batch of genomes.

    Args:
        genomes: (G, W) parent genomes, each gene in [low, high].
        rng: The GA's generator.
        sigma: Standard deviation of the Gaussian perturbation (> 0).
        probability: Per-gene mutation probability, in [0, 1].
        low: Lower gene bound.
        high: Upper gene bound (> low).
        max_redraws: Out-of-bounds draws allowed per gene before falling back to a
            uniform value in the bounds (>= 1).

    Returns:
        (G, W) float64 mutated copies; the input is not modified.
    """
    genomes = np.asarray(genomes, dtype=np.float64)
    if genomes.ndim != 2:
        raise ValueError(f"genomes must be (G, W), got shape {genomes.shape}")
    if not (np.isfinite(sigma) and sigma > 0):
        raise ValueError(f"mutation sigma must be positive and finite, got {sigma}")
    if not 0.0 <= probability <= 1.0:
        raise ValueError(f"mutation probability must be in [0, 1], got {probability}")
    if not low < high:
        raise ValueError(f"gene bounds must satisfy low < high, got [{low}, {high}]")
    if max_redraws < 1:
        raise ValueError(f"max_redraws must be at least 1, got {max_redraws}")
    children = genomes.copy()
    mutate = rng.random(genomes.shape) < probability
    parents = genomes[mutate]
    values = parents + sigma * rng.standard_normal(parents.size)
    out = (values < low) | (values > high)
    redraws = 1
    while out.any() and redraws < max_redraws:
        values[out] = parents[out] + sigma * rng.standard_normal(int(out.sum()))
        out = (values < low) | (values > high)
        redraws += 1
    if out.any():
        values[out] = rng.uniform(low, high, int(out.sum()))
    children[mutate] = values
    return children
