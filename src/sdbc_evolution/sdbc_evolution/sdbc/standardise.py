"""Feature standardisation (steps 4 and 6 of the paper's workflow).

Raw characterisations mix features of very different ranges (a group size in
[0, 1], a distance in arena units, a trial length in steps). Every generation, each
dimension k is z-scored with coefficients computed over the current population plus
the novelty archive, and the archive is re-standardised with the same coefficients:

    b'_k = clip((b_k - mu_k) / sigma_k, -c, c)

where sigma_k = 0 is read as 1 (a constant dimension stays 0) and c = 3 (docs/method.md,
from the authors' code: the three-sigma rule keeps one outlier from squashing a
dimension).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
from sdbc_sim.settings import Field, PositiveFloat, settings


@settings
class StandardisationSettings:
    """How raw characterisations are standardised."""

    clip: PositiveFloat = 3.0
    """c, standardised values are clipped to [-c, c]; docs/method.md: 3."""
    ddof: Annotated[int, Field(ge=0, le=1)] = 1
    """Delta degrees of freedom of sigma_k: 1 for the sample standard deviation as
    in the authors' code (the paper is silent), 0 for the population one."""


@dataclass(frozen=True)
class Standardisation:
    """Standardisation coefficients of one generation.

    Attributes:
        mean: (D,) mu_k.
        scale: (D,) sigma_k, with 0 (or an undefined SD of a single vector) read as 1.
        clip: c.
    """

    mean: np.ndarray
    scale: np.ndarray
    clip: float

    @classmethod
    def fit(
        cls,
        population: np.ndarray,
        archive: np.ndarray | None = None,
        settings: StandardisationSettings | None = None,
    ) -> Standardisation:
        """Coefficients over the population (n, D) plus the archive (m, D)."""
        settings = settings or StandardisationSettings()
        pool = _pool(population, archive)
        mean = pool.mean(axis=0)
        if pool.shape[0] > settings.ddof:
            scale = pool.std(axis=0, ddof=settings.ddof)
        else:
            scale = np.ones_like(mean)
        scale[scale == 0] = 1.0
        return cls(mean=mean, scale=scale, clip=settings.clip)

    def apply(self, vectors: np.ndarray) -> np.ndarray:
        """(n, D) raw vectors -> standardised, clipped vectors."""
        vectors = _checked(vectors, "vectors", self.mean.shape[0])
        z = (vectors - self.mean) / self.scale
        return np.clip(z, -self.clip, self.clip, out=z)


def _checked(array: np.ndarray, label: str, dimensions: int | None) -> np.ndarray:
    array = np.asarray(array, dtype=np.float64)
    if array.ndim != 2:
        raise ValueError(
            f"standardisation: {label} must be (n, D), got shape {array.shape}"
        )
    if dimensions is not None and array.shape[1] != dimensions:
        raise ValueError(
            f"standardisation: {label} have {array.shape[1]} dimensions, expected "
            f"{dimensions}"
        )
    if not np.isfinite(array).all():
        row = int(np.flatnonzero(~np.isfinite(array).all(axis=1))[0])
        raise ValueError(f"standardisation: {label} row {row} holds NaN or infinity")
    return array


def _pool(population: np.ndarray, archive: np.ndarray | None) -> np.ndarray:
    population = _checked(population, "population", None)
    if population.shape[0] == 0:
        raise ValueError("standardisation: the population is empty")
    if archive is None or np.size(archive) == 0:
        return population
    archive = _checked(archive, "archive", population.shape[1])
    return np.concatenate([population, archive])


def standardise(
    population: np.ndarray,
    archive: np.ndarray | None = None,
    settings: StandardisationSettings | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Standardises the population and the archive with the coefficients of both.

    Args:
        population: (n, D) raw characterisations of the current population.
        archive: (m, D) raw characterisations of the archive; None or empty for none.
        settings: Clip and SD settings.

    Returns:
        ``(population_z, archive_z)``, shaped as the inputs ((0, D) for no archive).
    """
    coefficients = Standardisation.fit(population, archive, settings)
    population_z = coefficients.apply(population)
    if archive is None or np.size(archive) == 0:
        return population_z, np.empty((0, population_z.shape[1]))
    return population_z, coefficients.apply(archive)
