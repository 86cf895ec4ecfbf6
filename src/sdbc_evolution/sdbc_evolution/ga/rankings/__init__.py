"""Rankings: how a scored generation becomes the order selection reads, registered in
one place (:data:`RANKINGS`).

A ranking is declared by name (``nsga2``) or as ``{name: {option: value}}``
(``{scalarised: {weight: 0.7}}``); :func:`parse_ranking` refuses unknown names and
bad options naming the part.

- ``nsga2`` (the paper): non-dominated fronts on (fitness, novelty), then
  ``novelty.tie_break`` inside a front (:mod:`.nsga2`).
- ``fitness``: fitness alone (the paper's Fit; no characterisation).
- ``novelty``: novelty alone (pure novelty search).
- ``nslc``: NSGA-II on (novelty, local competition) (Lehman & Stanley 2011).
- ``scalarised``: w fitness + (1 - w) novelty, both min-max normalised.
- ``minimal_criterion``: novelty among those that meet a fitness criterion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sdbc_sim.settings import Fraction, PositiveInt, settings

from sdbc_evolution.ga.rankings.nsga2 import nsga2_order
from sdbc_evolution.ga.rankings.others import (
    fitness_ranking,
    local_competition,
    minimal_criterion_ranking,
    novelty_ranking,
    scalarised_ranking,
)
from sdbc_evolution.sdbc.declared import changed_options, declared_part


@settings
class NoOptions:
    """This ranking has no options."""


@settings
class NslcOptions:
    """Novelty search with local competition."""

    k: PositiveInt | None = None
    """Neighbours of the local competition; None: the novelty metric's k."""


@settings
class ScalarisedOptions:
    """Linear scalarisation."""

    weight: Fraction = 0.5
    """w, the share of (normalised) fitness; 1 - w goes to novelty."""


@settings
class MinimalCriterionOptions:
    """Minimal-criterion novelty search."""

    criterion: float | None = None
    """The fitness an individual must reach; None: the population's median."""


@dataclass(frozen=True)
class Ranking:
    """A registered ranking."""

    options: type
    uses_novelty: bool
    summary: str


RANKINGS: dict[str, Ranking] = {
    "nsga2": Ranking(NoOptions, True, "NSGA-II on (fitness, novelty) (paper)"),
    "fitness": Ranking(NoOptions, False, "fitness alone"),
    "novelty": Ranking(NoOptions, True, "novelty alone"),
    "nslc": Ranking(NslcOptions, True, "NSGA-II on (novelty, local competition)"),
    "scalarised": Ranking(ScalarisedOptions, True, "w fitness + (1 - w) novelty"),
    "minimal_criterion": Ranking(
        MinimalCriterionOptions, True, "novelty among those meeting a criterion"
    ),
}
"""Every ranking, by name."""


@dataclass(frozen=True)
class RankingSpec:
    """A declared ranking and its options."""

    name: str
    options: Any

    @property
    def uses_novelty(self) -> bool:
        """Whether it needs novelty scores (and so a characterisation)."""
        return RANKINGS[self.name].uses_novelty

    def to_plain(self) -> str | dict[str, Any]:
        """The declaration, YAML-ready: the name alone for default options."""
        changed = changed_options(self.options)
        return {self.name: changed} if changed else self.name

    def rank(
        self,
        fitness: np.ndarray,
        novelty: np.ndarray | None,
        population: np.ndarray | None,
        archive: np.ndarray | None,
        archive_fitness: np.ndarray | None,
        k: int,
        tie_break: str,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(order, front)`` of a generation.

        Args:
            fitness: (N,) fitness.
            novelty: (N,) novelty scores (None when the ranking uses none).
            population: (N, D) transformed behaviour vectors (NSLC).
            archive: (M, D) transformed archive vectors (NSLC).
            archive_fitness: (M,) fitness of the archive's entries (NSLC).
            k: The novelty metric's k.
            tie_break: The order inside an NSGA-II front (``novelty.tie_break``).
        """
        name, options = self.name, self.options
        if name == "fitness":
            return fitness_ranking(fitness)
        novelty = _given(novelty, "novelty", name)
        if name == "nsga2":
            order, front, _ = nsga2_order(
                np.column_stack([fitness, novelty]), tie_break=tie_break
            )
            return order, front
        if name == "novelty":
            return novelty_ranking(novelty)
        if name == "nslc":
            competition = local_competition(
                _given(population, "behaviour vectors", name),
                _given(archive, "archive vectors", name),
                fitness,
                _given(archive_fitness, "archive fitness", name),
                options.k or k,
            )
            order, front, _ = nsga2_order(np.column_stack([novelty, competition]))
            return order, front
        if name == "scalarised":
            return scalarised_ranking(fitness, novelty, options.weight)
        return minimal_criterion_ranking(fitness, novelty, options.criterion)


def _given(array: np.ndarray | None, what: str, ranking: str) -> np.ndarray:
    if array is None:
        raise ValueError(f"ranking {ranking!r} needs the {what}")
    return array


def parse_ranking(declaration: Any, where: str = "ranking") -> RankingSpec:
    """A spec from ``name`` or ``{name: {option: value}}``.

    Raises:
        SettingsError: Unknown ranking or bad options, naming ``where``.
    """
    if isinstance(declaration, RankingSpec):
        return declaration
    options = {name: r.options for name, r in RANKINGS.items()}
    return RankingSpec(*declared_part(declaration, options, "ranking", where))
