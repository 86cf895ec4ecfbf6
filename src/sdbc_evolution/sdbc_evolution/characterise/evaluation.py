"""What an evaluation of a generation carries: fitness and named behaviour arrays.

Every characterisation a run asks for (see :mod:`.registry`) comes back as one
(G, D) array of per-controller vectors (the mean over the controller's trials),
under the characterisation's key. Nothing here knows which characterisations exist;
two are always there, because the run's outputs and the study read them:
:data:`TASK` (the task-specific characterisation) and :data:`SDBC` (the paper's SDBC).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TASK = "task"
"""Key of the task-specific characterisation."""
SDBC = "sdbc"
"""Key of the paper's SDBC (default options)."""


@dataclass
class Evaluation:
    """The evaluation of G controllers in T trials each.

    Attributes:
        fitness: (G,) controller fitness (the engine's aggregate over trials).
        trial_fitness: (G, T) fitness of every trial.
        behaviours: characterisation key -> (G, D) vectors, mean over trials.
    """

    fitness: np.ndarray
    trial_fitness: np.ndarray
    behaviours: dict[str, np.ndarray]

    @property
    def characterisation(self) -> np.ndarray:
        """(G, C) the task-specific characterisation."""
        return self.behaviour(TASK)

    @property
    def sdbc(self) -> np.ndarray:
        """(G, D) the paper's raw SDBC vectors."""
        return self.behaviour(SDBC)

    def behaviour(self, key: str) -> np.ndarray:
        """The (G, D) vectors of the characterisation ``key``."""
        try:
            return self.behaviours[key]
        except KeyError:
            raise KeyError(
                f"this evaluation has no characterisation {key!r}; it has "
                f"{sorted(self.behaviours)}"
            ) from None

    @classmethod
    def concatenate(cls, parts: list[Evaluation]) -> Evaluation:
        """Joins the evaluations of consecutive chunks."""
        keys = parts[0].behaviours.keys()
        return cls(
            fitness=np.concatenate([p.fitness for p in parts]),
            trial_fitness=np.concatenate([p.trial_fitness for p in parts]),
            behaviours={
                k: np.concatenate([p.behaviours[k] for p in parts]) for k in keys
            },
        )
