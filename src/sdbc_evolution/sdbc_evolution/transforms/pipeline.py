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

Each is a part (:class:`~.base.Transform`, registered in :data:`TRANSFORMS`, open to
the entry point group ``sdbc.transforms``). Declared as a list, in order:
``[standardise, {weight: {relevance: mi_chance}}]``. Each transform appears at most
once, and one that names others in ``after`` (weight names standardise:
standardising weighted values would undo the weights) comes after them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from pydantic import BeforeValidator
from sdbc_sim.limits import excerpt
from sdbc_sim.parts import PartSpec, Registry, at
from sdbc_sim.settings import Field, SettingsError, settings

from sdbc_evolution.relevance.measures import RelevanceSpec, parse_relevance
from sdbc_evolution.sdbc.standardise import StandardisationSettings, standardise
from sdbc_evolution.sdbc.weighting import WeightingSettings
from sdbc_evolution.transforms.base import (
    Transform,
    TransformContext,
    TransformStep,
)

ENTRY_POINT_GROUP = "sdbc.transforms"
"""Entry point group of transforms from other distributions."""


class Standardise(Transform):
    """Z-scores against population + archive, clipped (paper).

    Its settings are the run's ``standardisation`` section, not options."""

    def apply(
        self, population: np.ndarray, archive: np.ndarray, context: TransformContext
    ) -> TransformStep:
        return TransformStep(*standardise(population, archive, context.standardisation))


def _canonical_relevance(value: Any) -> Any:
    # Kept as its canonical declaration, so that options compare (and round-trip)
    # by meaning: {mi: {}} is mi.
    return parse_relevance(value, "").to_plain()


@settings
class WeightOptions:
    """Relevance weighting."""

    relevance: Annotated[
        str | dict[str, Any], BeforeValidator(_canonical_relevance)
    ] = "mi"
    """The relevance measure: a name or ``{name: options}``."""
    smoothing: Annotated[float, Field(ge=0, lt=1)] = 0.0
    """s in [0, 1): the share of the weights in force kept at each update (0, the
    paper: none)."""

    @property
    def measure(self) -> RelevanceSpec:
        """The parsed relevance measure."""
        return parse_relevance(self.relevance, "relevance")


class Weight(Transform):
    """Every dimension times delta + its relevance to fitness (paper, NS-SD+)."""

    options_class = WeightOptions
    after = ("standardise",)
    why_after = "standardising weighted values would undo the weights"

    def apply(
        self, population: np.ndarray, archive: np.ndarray, context: TransformContext
    ) -> TransformStep:
        weighting, weights = context.weighting, context.weights
        relevance = None
        if weights is None or context.generation % weighting.update_every == 0:
            relevance = self.options.measure.compute(
                context.raw, context.fitness, weighting, context.rng
            )
            new = weighting.delta + relevance
            s = self.options.smoothing
            weights = new if weights is None or s == 0 else (1 - s) * new + s * weights
        return TransformStep(
            population * weights, archive * weights, weights, relevance
        )


TRANSFORMS: Registry[Transform] = Registry("transform", ENTRY_POINT_GROUP, Transform)
"""Every transform, by name."""
TRANSFORMS.register("standardise", Standardise)
TRANSFORMS.register("weight", Weight)


@dataclass(frozen=True)
class TransformSpec(PartSpec[Transform]):
    """One declared transform."""

    registry = TRANSFORMS


def parse_transforms(
    declaration: Any, where: str = "transforms"
) -> tuple[TransformSpec, ...]:
    """Transform specs from a list of ``name`` or ``{name: options}``.

    Raises:
        SettingsError: Unknown transform, bad options, a repeated transform or
            one before a transform it must follow, naming the part.
    """
    if declaration is None:
        return ()
    if not isinstance(declaration, (list, tuple)):
        raise SettingsError.of(
            ((where, f"expected a list of transforms, got {excerpt(declaration)}"),)
        )
    specs = tuple(
        TransformSpec.parse(item, at(where, str(i)))
        for i, item in enumerate(declaration)
    )
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise SettingsError.of(((where, f"a transform appears twice in {names}"),))
    for i, spec in enumerate(specs):
        part = spec.registered.part
        for earlier in part.after:
            if earlier in names[i + 1 :]:
                raise SettingsError.of(
                    (
                        (
                            where,
                            f"{spec.name} must come after {earlier} (got {names}); "
                            f"{part.why_after}",
                        ),
                    )
                )
    return specs


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
    standardisation: StandardisationSettings | None,
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

    Raises:
        ValueError: A transform's answer whose population and archive do not
            keep their rows or agree on their columns, naming the transform.
    """
    context = TransformContext(
        raw, fitness, weights, generation, rng, standardisation, weighting
    )
    population, archived = raw, archive
    relevance = None
    kept_weights = None
    for spec in transforms:
        step = spec.build().apply(population, archived, context)
        population, archived = _checked_step(spec.name, step, population, archived)
        if step.weights is not None:
            kept_weights = step.weights
        if step.relevance is not None:
            relevance = step.relevance
    return Transformed(population, archived, kept_weights, relevance)


def _checked_step(
    name: str, step: Any, population: np.ndarray, archive: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(step, TransformStep):
        raise ValueError(
            f"transform {name!r} returned {type(step).__name__}, expected a "
            "TransformStep"
        )
    new_population = np.asarray(step.population, dtype=np.float64)
    new_archive = np.asarray(step.archive, dtype=np.float64)
    rows = (population.shape[0], np.shape(archive)[0])
    if (
        new_population.ndim != 2
        or new_archive.ndim != 2
        or (new_population.shape[0], new_archive.shape[0]) != rows
        or new_archive.shape[1] != new_population.shape[1]
    ):
        raise ValueError(
            f"transform {name!r} returned population {new_population.shape} and "
            f"archive {new_archive.shape} from {population.shape} and "
            f"{np.shape(archive)}: rows must stay, columns must agree"
        )
    return new_population, new_archive
