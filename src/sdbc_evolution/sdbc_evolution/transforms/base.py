"""What a transform is: a part (:mod:`sdbc_sim.parts`) that maps a generation's
behaviour vectors, population and archive alike, before novelty is scored."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from sdbc_sim.parts import NoOptions

from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings


@dataclass(frozen=True)
class TransformContext:
    """What a transform may read of one generation besides the vectors.

    Attributes:
        raw: (N, D) raw behaviour vectors of the population (before any
            transform).
        fitness: (N,) fitness of the population.
        weights: The weights in force from an earlier generation, or None.
        generation: This generation's index (0-based).
        rng: The GA's generator; every draw is part of the run's resume
            contract, so a transform draws the same number each generation it
            updates.
        standardisation: The run's ``standardisation`` settings.
        weighting: The run's ``weighting`` settings.
    """

    raw: np.ndarray
    fitness: np.ndarray
    weights: np.ndarray | None
    generation: int
    rng: np.random.Generator
    standardisation: StandardisationSettings | None
    weighting: WeightingSettings


@dataclass(frozen=True)
class TransformStep:
    """A transform's answer.

    Attributes:
        population: (N, D') the transformed population.
        archive: (M, D') the transformed archive.
        weights: (D',) weights it put in force (the run records them), or None.
        relevance: (D',) relevance it computed this generation, or None.
    """

    population: np.ndarray
    archive: np.ndarray
    weights: np.ndarray | None = None
    relevance: np.ndarray | None = None


class Transform(ABC):
    """A transform: made from its options, asked through :meth:`apply`.

    Class attributes:
        options_class: Its options (a settings class, every option defaulted).
        after: Transforms that, when declared with it, must come before it.
        why_after: Why, for the message that refuses another order.
    """

    options_class: ClassVar[type] = NoOptions
    after: ClassVar[tuple[str, ...]] = ()
    why_after: ClassVar[str] = ""

    def __init__(self, options: Any = None) -> None:
        self.options = self.options_class() if options is None else options

    @abstractmethod
    def apply(
        self, population: np.ndarray, archive: np.ndarray, context: TransformContext
    ) -> TransformStep:
        """The transformed ``population`` (N, D) and ``archive`` (M, D) (the
        output of the transforms declared before it)."""
