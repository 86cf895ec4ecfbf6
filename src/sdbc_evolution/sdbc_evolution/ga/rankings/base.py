"""What a ranking is: a part (:mod:`sdbc_sim.parts`) that turns a scored
generation, a :class:`RankingContext`, into the order selection reads.

A ranking returns ``(order, front)``: individual indices best first, and a front
index per individual (0 for all where the ranking has no fronts).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar, NamedTuple

import numpy as np
from sdbc_sim.parts import NoOptions


class Ranked(NamedTuple):
    """A ranking's answer."""

    order: np.ndarray
    """(N,) individual indices, best first (a permutation of 0..N-1)."""
    front: np.ndarray
    """(N,) int front of every individual (0 where the ranking has none)."""


@dataclass(frozen=True)
class RankingContext:
    """Everything a ranking may read of one generation.

    Attributes:
        fitness: (N,) fitness.
        novelty: (N,) novelty scores; None without a characterisation.
        population: (N, D) transformed behaviour vectors; None without one.
        archive: (M, D) transformed vectors of the archive before this
            generation's additions; None without a characterisation.
        archive_fitness: (M,) fitness of those archive entries.
        k: The novelty metric's k.
        tie_break: The order inside an NSGA-II front (``novelty.tie_break``).
        rng: The GA's generator. A ranking that draws from it changes every later
            draw of the run, so it must say so (:attr:`Ranking.draws`); the
            paper's draw nothing.
    """

    fitness: np.ndarray
    novelty: np.ndarray | None
    population: np.ndarray | None
    archive: np.ndarray | None
    archive_fitness: np.ndarray | None
    k: int
    tie_break: str
    rng: np.random.Generator

    @property
    def size(self) -> int:
        """N, the generation's size."""
        return int(np.shape(self.fitness)[0])

    def given(self, attribute: str, ranking: str) -> np.ndarray:
        """The array ``attribute``, refused in one line naming ``ranking`` if the
        generation has none."""
        value = getattr(self, attribute)
        if value is None:
            raise ValueError(f"ranking {ranking!r} needs the {attribute}")
        return np.asarray(value, dtype=np.float64)


class Ranking(ABC):
    """A ranking: made from its options, asked through :meth:`rank`.

    Class attributes:
        options_class: Its options (a settings class, every option defaulted).
        uses_novelty: It reads novelty, so the treatment needs a
            characterisation; one that does not needs ``characterisation: none``.
        draws: It draws from the context's generator.
    """

    options_class: ClassVar[type] = NoOptions
    uses_novelty: ClassVar[bool] = True
    draws: ClassVar[bool] = False

    def __init__(self, options: Any = None) -> None:
        self.options = self.options_class() if options is None else options

    @abstractmethod
    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        """``(order, front)`` of the generation (see :class:`Ranked`)."""


def checked_ranking(name: str, answer: Any, size: int) -> Ranked:
    """A ranking's answer, refused in one line naming the ranking unless it is an
    order of all ``size`` individuals and a front for each."""
    try:
        order, front = answer
    except (TypeError, ValueError):
        raise ValueError(
            f"ranking {name!r} returned {type(answer).__name__}, expected "
            "(order, front)"
        ) from None
    order = np.asarray(order)
    front = np.asarray(front)
    if order.shape != (size,) or order.dtype.kind not in "iu":
        raise ValueError(
            f"ranking {name!r}: order has shape {order.shape} and dtype "
            f"{order.dtype}, expected ({size},) integers"
        )
    if not np.array_equal(np.sort(order), np.arange(size)):
        raise ValueError(
            f"ranking {name!r}: order is not a permutation of the {size} individuals"
        )
    if front.shape != (size,) or front.dtype.kind not in "iu":
        raise ValueError(
            f"ranking {name!r}: front has shape {front.shape} and dtype "
            f"{front.dtype}, expected ({size},) integers"
        )
    return Ranked(
        order.astype(np.int64, copy=False), front.astype(np.int64, copy=False)
    )
