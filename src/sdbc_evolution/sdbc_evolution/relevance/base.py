"""What a relevance measure is: a part (:mod:`sdbc_sim.parts`) that says how much
each dimension of a population's raw behaviour vectors tells about its fitness."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np
from sdbc_sim.parts import NoOptions

from sdbc_evolution.sdbc.weighting import WeightingSettings


class RelevanceMeasure(ABC):
    """A relevance measure: made from its options, asked through
    :meth:`relevance`.

    Class attributes:
        options_class: Its options (a settings class, every option defaulted).
    """

    options_class: ClassVar[type] = NoOptions

    def __init__(self, options: Any = None) -> None:
        self.options = self.options_class() if options is None else options

    @abstractmethod
    def relevance(
        self,
        raw: np.ndarray,
        fitness: np.ndarray,
        weighting: WeightingSettings,
        seed: int,
    ) -> np.ndarray:
        """(D,) relevance, finite and at least 0, of every dimension of ``raw``
        (n, D) to ``fitness`` (n,), both float64 and finite.

        Args:
            raw: The population's raw behaviour vectors.
            fitness: Its fitness.
            weighting: The run's weighting settings (discretisation of MI).
            seed: Seeds whatever the measure draws (it must be a function of its
                arguments: the caller drew ``seed`` from the run's generator).
        """
