"""The transforms a treatment declares between its characterisation and novelty.

- ``standardise`` (the paper, NS-SD and NS-SD+): z-scores against population +
  archive, clipped (:mod:`sdbc_evolution.sdbc.standardise`, settings from the run's
  ``standardisation`` section).
- ``weight`` (the paper, NS-SD+): every dimension k multiplied by
  w_k = delta + relevance_k, with the relevance measure of the declaration
  (:mod:`sdbc_evolution.relevance.measures`; ``mi`` is the paper's) on the raw vectors
  of the current population, recomputed every ``weighting.update_every``
  generations (delta and the discretisation also from the run's ``weighting``
  section). With ``smoothing: s`` > 0 the new weights are blended with those in force,
  w <- (1 - s) w_new + s w_old (the authors' later code's weight smoothing).

Declared as a list, in order: ``[standardise, {weight: {relevance: mi_chance}}]``.
Weighting must come after standardisation (standardising weighted values would undo
the weights), and each transform appears at most once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Any

import numpy as np
from sdbc_sim.limits import excerpt
from sdbc_sim.settings import Field, SettingsError, settings

from sdbc_evolution.relevance.measures import RelevanceSpec, parse_relevance
from sdbc_evolution.sdbc.declared import at, declared_part
from sdbc_evolution.sdbc.standardise import StandardisationSettings, standardise
from sdbc_evolution.sdbc.weighting import WeightingSettings

TRANSFORMS = ("standardise", "weight")
"""Transform names, in the only order they may come."""


@settings
class StandardiseOptions:
    """Standardisation takes its settings from the run's ``standardisation``."""


@settings
class WeightOptions:
    """Relevance weighting."""

    relevance: str | dict[str, Any] = "mi"
    """The relevance measure: a name or ``{name: options}``."""
    smoothing: Annotated[float, Field(ge=0, lt=1)] = 0.0
    """s in [0, 1): the share of the weights in force kept at each update (0, the
    paper: none)."""

    def __post_init__(self) -> None:
        parse_relevance(self.relevance, "relevance")

    @property
    def measure(self) -> RelevanceSpec:
        """The parsed relevance measure."""
        return parse_relevance(self.relevance, "relevance")


_OPTIONS = {"standardise": StandardiseOptions, "weight": WeightOptions}


@dataclass(frozen=True)
class TransformSpec:
    """One declared transform."""

    name: str
    options: Any = field(default=None)

    def to_plain(self) -> str | dict[str, Any]:
        """The declaration, YAML-ready."""
        if isinstance(self.options, WeightOptions):
            changed: dict[str, Any] = {}
            if self.options.relevance != "mi":
                changed["relevance"] = self.options.measure.to_plain()
            if self.options.smoothing:
                changed["smoothing"] = self.options.smoothing
            return {self.name: changed} if changed else self.name
        return self.name


def parse_transforms(
    declaration: Any, where: str = "transforms"
) -> tuple[TransformSpec, ...]:
    """Transform specs from a list of ``name`` or ``{name: options}``.

    Raises:
        SettingsError: Unknown transform, bad options, a repeated transform or
            weighting before standardisation, naming the part.
    """
    if declaration is None:
        return ()
    if not isinstance(declaration, (list, tuple)):
        raise SettingsError.of(
            ((where, f"expected a list of transforms, got {excerpt(declaration)}"),)
        )
    specs: list[TransformSpec] = []
    for i, item in enumerate(declaration):
        if isinstance(item, TransformSpec):
            specs.append(item)
            continue
        here = at(where, str(i))
        specs.append(TransformSpec(*declared_part(item, _OPTIONS, "transform", here)))
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise SettingsError.of(((where, f"a transform appears twice in {names}"),))
    if names != sorted(names, key=TRANSFORMS.index):
        raise SettingsError.of(
            (
                (
                    where,
                    f"weight must come after standardise (got {names}); "
                    "standardising weighted values would undo the weights",
                ),
            )
        )
    return tuple(specs)


@dataclass
class Transformed:
    """Behaviour vectors ready for the novelty metric.

    Attributes:
        population: (N, D) transformed vectors of the population.
        archive: (M, D) transformed vectors of the archive.
        weights: (D,) the weights in force after this generation, or None.
        relevance: (D,) the relevance computed this generation, or None.
    """

    population: np.ndarray
    archive: np.ndarray
    weights: np.ndarray | None
    relevance: np.ndarray | None


def apply_transforms(
    transforms: tuple[TransformSpec, ...],
    raw: np.ndarray,
    archive: np.ndarray,
    fitness: np.ndarray,
    weights: np.ndarray | None,
    generation: int,
    rng: np.random.Generator,
    standardisation: StandardisationSettings,
    weighting: WeightingSettings,
) -> Transformed:
    """Applies the transforms in order to a generation's raw vectors.

    Args:
        transforms: The declared transforms.
        raw: (N, D) raw vectors of the population.
        archive: (M, D) raw vectors of the archive.
        fitness: (N,) fitness of the population.
        weights: The weights in force from an earlier generation, or None.
        generation: This generation's index (0-based).
        rng: The GA's generator (a weight update draws one integer from it).
        standardisation: The run's standardisation settings.
        weighting: The run's weighting settings.
    """
    population, archived = raw, archive
    relevance = None
    kept_weights = None
    for spec in transforms:
        if spec.name == "standardise":
            population, archived = standardise(population, archived, standardisation)
        else:
            if weights is None or generation % weighting.update_every == 0:
                relevance = spec.options.measure.compute(raw, fitness, weighting, rng)
                new = weighting.delta + relevance
                s = spec.options.smoothing
                weights = (
                    new if weights is None or s == 0 else (1 - s) * new + s * weights
                )
            population = population * weights
            archived = archived * weights
            kept_weights = weights
    return Transformed(population, archived, kept_weights, relevance)
