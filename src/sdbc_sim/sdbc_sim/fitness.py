"""How a controller's fitness sums up its trials.

Apart from the engine so that the method (``sdbc_evolution``'s ask/tell object)
sums trials up as the engine does without loading the simulator.
"""

from __future__ import annotations

import numpy as np

FITNESS_MEANS = ("harmonic", "arithmetic")
"""The ways a controller's trials are summed up."""
HARMONIC_FLOOR = 1e-4
"""A trial's fitness counts as at least this in the harmonic mean (authors' code)."""


def controller_fitness(fitness: np.ndarray, mean: str = "harmonic") -> np.ndarray:
    """(G,) fitness of each controller from its trials' (G, T) fitness.

    harmonic: T / sum_t 1 / max(F_t, 1e-4); arithmetic: sum_t F_t / T.
    """
    if mean == "harmonic":
        return fitness.shape[1] / np.sum(
            1.0 / np.maximum(fitness, HARMONIC_FLOOR), axis=1
        )
    if mean == "arithmetic":
        return fitness.mean(axis=1)
    raise ValueError(
        f"unknown fitness mean {mean!r}; known: {', '.join(FITNESS_MEANS)}"
    )
