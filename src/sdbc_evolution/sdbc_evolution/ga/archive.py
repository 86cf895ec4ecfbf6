"""The novelty archive: a bounded random sample of past behaviours.

Policy (docs/reference-setup.md, "Evolution", after the authors' code): after
novelty has been scored, every individual of the generation is added with probability p
(0.03); once the archive holds its maximum (1000) entries, a new entry replaces one
chosen uniformly at random. Individuals are offered in population order, each drawing
one uniform number, and each replacement draws one index, all from the GA's generator,
so the archive is a function of the run's seed.

The archive keeps the *raw* behaviour vectors: SDBC vectors are re-standardised
against population + archive every generation, so standardised values would go stale.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class NoveltyArchive:
    """Behaviour vectors of past individuals, with their fitness and generation.

    Attributes:
        capacity: Most entries held; 0 disables the archive.
        probability: Chance that an offered individual is added.
        behaviours: (A, D) raw behaviour vectors, A <= capacity.
        fitness: (A,) fitness of each entry when it was added.
        generation: (A,) generation in which each entry was added.
    """

    capacity: int
    probability: float
    behaviours: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    fitness: np.ndarray = field(default_factory=lambda: np.zeros(0))
    generation: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        if self.capacity < 0:
            raise ValueError(f"archive capacity must be >= 0, got {self.capacity}")
        if not 0.0 <= self.probability <= 1.0:
            raise ValueError(
                f"archive probability must be in [0, 1], got {self.probability}"
            )
        self.behaviours = np.asarray(self.behaviours, dtype=np.float64)
        self.fitness = np.asarray(self.fitness, dtype=np.float64)
        self.generation = np.asarray(self.generation, dtype=np.int64)
        size = self.behaviours.shape[0]
        if (
            self.behaviours.ndim != 2
            or self.fitness.shape != (size,)
            or (self.generation.shape != (size,))
        ):
            raise ValueError(
                "archive arrays disagree: behaviours "
                f"{self.behaviours.shape}, fitness {self.fitness.shape}, "
                f"generation {self.generation.shape}"
            )
        if size > self.capacity:
            raise ValueError(f"archive holds {size} entries, capacity {self.capacity}")

    def __len__(self) -> int:
        return int(self.behaviours.shape[0])

    def offer(
        self,
        behaviours: np.ndarray,
        fitness: np.ndarray,
        generation: int,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """Offers a generation's individuals to the archive.

        Args:
            behaviours: (N, D) raw behaviour vectors, in population order.
            fitness: (N,) their fitness.
            generation: The generation they belong to.
            rng: The GA's generator (one uniform per individual, one index per
                replacement).

        Returns:
            (N,) bool: which individuals entered the archive.
        """
        behaviours = np.asarray(behaviours, dtype=np.float64)
        fitness = np.asarray(fitness, dtype=np.float64)
        if behaviours.ndim != 2 or fitness.shape != (behaviours.shape[0],):
            raise ValueError(
                f"behaviours {behaviours.shape} and fitness {fitness.shape} disagree"
            )
        if len(self) and behaviours.shape[1] != self.behaviours.shape[1]:
            raise ValueError(
                f"behaviours have {behaviours.shape[1]} dimensions, the archive "
                f"{self.behaviours.shape[1]}"
            )
        if len(self) == 0:
            self.behaviours = np.zeros((0, behaviours.shape[1]))
        added = rng.random(len(behaviours)) < self.probability
        if self.capacity == 0:
            return np.zeros_like(added)
        for i in np.flatnonzero(added):
            if len(self) < self.capacity:
                self.behaviours = np.concatenate(
                    [self.behaviours, behaviours[i : i + 1]]
                )
                self.fitness = np.append(self.fitness, fitness[i])
                self.generation = np.append(self.generation, generation)
            else:
                slot = int(rng.integers(self.capacity))
                self.behaviours[slot] = behaviours[i]
                self.fitness[slot] = fitness[i]
                self.generation[slot] = generation
        return added

    def state(self) -> dict[str, np.ndarray]:
        """The archive as plain arrays (for checkpoints)."""
        return {
            "behaviours": self.behaviours.copy(),
            "fitness": self.fitness.copy(),
            "generation": self.generation.copy(),
        }
