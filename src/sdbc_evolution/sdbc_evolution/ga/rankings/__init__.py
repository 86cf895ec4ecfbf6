"""Rankings: how a scored generation becomes the order selection reads, registered in
one place (:data:`RANKINGS`), open to the entry point group ``sdbc.rankings``.

A ranking is a part (:mod:`sdbc_sim.parts`): a :class:`~.base.Ranking` subclass with
an options class, asked through ``rank(context)`` with a
:class:`~.base.RankingContext`. It is declared by name (``nsga2``) or as
``{name: {option: value}}`` (``{scalarised: {weight: 0.7}}``); :func:`parse_ranking`
refuses unknown names and bad options naming the part.

- ``nsga2`` (the paper): non-dominated fronts on (fitness, novelty), then
  ``novelty.tie_break`` inside a front (:mod:`.nsga2`).
- ``fitness``: fitness alone (the paper's Fit; no characterisation).
- ``novelty``: novelty alone (pure novelty search).
- ``nslc``: NSGA-II on (novelty, local competition) (Lehman & Stanley 2011).
- ``scalarised``: w fitness + (1 - w) novelty, both min-max normalised.
- ``minimal_criterion``: novelty among those that meet a fitness criterion.

None of them draws from the generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sdbc_sim.parts import PartSpec, Registry
from sdbc_sim.settings import Fraction, PositiveInt, settings

from sdbc_evolution.ga.rankings.base import (
    NoOptions,
    Ranked,
    Ranking,
    RankingContext,
    checked_ranking,
)
from sdbc_evolution.ga.rankings.nsga2 import nsga2_order
from sdbc_evolution.ga.rankings.others import (
    fitness_ranking,
    local_competition,
    minimal_criterion_ranking,
    novelty_ranking,
    scalarised_ranking,
)

__all__ = [
    "RANKINGS",
    "NoOptions",
    "Ranked",
    "Ranking",
    "RankingContext",
    "RankingSpec",
    "parse_ranking",
]

ENTRY_POINT_GROUP = "sdbc.rankings"
"""Entry point group of rankings from other distributions."""


class Nsga2(Ranking):
    """NSGA-II on (fitness, novelty) (paper)."""

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        novelty = context.given("novelty", "nsga2")
        order, front, _ = nsga2_order(
            np.column_stack([context.fitness, novelty]), tie_break=context.tie_break
        )
        return order, front


class FitnessAlone(Ranking):
    """Fitness alone."""

    uses_novelty = False

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        return fitness_ranking(context.fitness)


class NoveltyAlone(Ranking):
    """Novelty alone."""

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        return novelty_ranking(context.given("novelty", "novelty"))


@settings
class NslcOptions:
    """Novelty search with local competition."""

    k: PositiveInt | None = None
    """Neighbours of the local competition; None: the novelty metric's k."""


class Nslc(Ranking):
    """NSGA-II on (novelty, local competition)."""

    options_class = NslcOptions

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        competition = local_competition(
            context.given("population", "nslc"),
            context.given("archive", "nslc"),
            context.fitness,
            context.given("archive_fitness", "nslc"),
            self.options.k or context.k,
        )
        novelty = context.given("novelty", "nslc")
        order, front, _ = nsga2_order(np.column_stack([novelty, competition]))
        return order, front


@settings
class ScalarisedOptions:
    """Linear scalarisation."""

    weight: Fraction = 0.5
    """w, the share of (normalised) fitness; 1 - w goes to novelty."""


class Scalarised(Ranking):
    """w fitness + (1 - w) novelty."""

    options_class = ScalarisedOptions

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        novelty = context.given("novelty", "scalarised")
        return scalarised_ranking(context.fitness, novelty, self.options.weight)


@settings
class MinimalCriterionOptions:
    """Minimal-criterion novelty search."""

    criterion: float | None = None
    """The fitness an individual must reach; None: the population's median."""


class MinimalCriterion(Ranking):
    """Novelty among those meeting a criterion."""

    options_class = MinimalCriterionOptions

    def rank(self, context: RankingContext) -> tuple[np.ndarray, np.ndarray]:
        novelty = context.given("novelty", "minimal_criterion")
        return minimal_criterion_ranking(
            context.fitness, novelty, self.options.criterion
        )


RANKINGS: Registry[Ranking] = Registry("ranking", ENTRY_POINT_GROUP, Ranking)
"""Every ranking, by name."""
RANKINGS.register("nsga2", Nsga2)
RANKINGS.register("fitness", FitnessAlone)
RANKINGS.register("novelty", NoveltyAlone)
RANKINGS.register("nslc", Nslc)
RANKINGS.register("scalarised", Scalarised)
RANKINGS.register("minimal_criterion", MinimalCriterion)


@dataclass(frozen=True)
class RankingSpec(PartSpec[Ranking]):
    """A declared ranking and its options."""

    registry = RANKINGS

    @property
    def uses_novelty(self) -> bool:
        """Whether it needs novelty scores (and so a characterisation)."""
        return self.registered.part.uses_novelty

    def rank(self, context: RankingContext) -> Ranked:
        """``(order, front)`` of a generation, checked (one-line ValueError naming
        the ranking for an answer that is not an order of the generation)."""
        answer = self.build().rank(context)
        return checked_ranking(self.name, answer, context.size)


def parse_ranking(declaration: object, where: str = "ranking") -> RankingSpec:
    """A spec from ``name`` or ``{name: {option: value}}``.

    Raises:
        SettingsError: Unknown ranking or bad options, naming ``where``.
    """
    return RankingSpec.parse(declaration, where)
