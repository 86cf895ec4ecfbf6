"""How much a task's exploration numbers and verdicts depend on its map.

The exploration claims (:func:`sdbc_evolution.study.claims.exploration_claims`)
rest on one SOM per task: one seed, one grid, one size of the high-fitness region.
Here they are judged again, by the same rules (Holm within the task's exploration
tests), on other readings of the runs:

- **other maps** (``"map"``): the map trained again for several seeds and grids
  (:class:`~.exploration.Sensitivity`, in a digest only where the analysis of the
  run directories asked for it, ``sdbc-study analyse --som-seeds N``);
- **other region sizes** (``"region"``): the study's own map with the high-fitness
  region made of :data:`~.exploration.REGION_FRACTIONS` of the occupied units,
  which every digest allows (it keeps the map's per-unit counts and percentiles).

For each, every treatment's mean high-fitness share (over its runs) and mean
uniformity per setting, and for each claim its verdict per setting beside the
verdict on the study's map: the fraction of settings with the same verdict says
how far the verdict is the data's rather than the map's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sdbc_evolution.study.claims import ALPHA, Verdict, exploration_claims
from sdbc_evolution.study.exploration import (
    REGION_FRACTIONS,
    ExplorationMaps,
    RunMetrics,
)

MAP, REGION = "map", "region"
"""The two kinds of settings (see the module docstring)."""
REGION_STATISTIC = "per-run high-fitness share of the SOM map"
"""The statistic of the exploration claims a region's size can move."""


@dataclass(frozen=True)
class Setting:
    """One reading of the runs: a map or a region size, and the runs' numbers.

    Attributes:
        kind: :data:`MAP` or :data:`REGION`.
        seed: The map's seed.
        rows: The map's rows.
        columns: The map's columns.
        fraction: The region's share of the occupied units.
        metrics: Each run's uniformity and high-fitness share.
    """

    kind: str
    seed: int
    rows: int
    columns: int
    fraction: float
    metrics: RunMetrics

    @property
    def label(self) -> str:
        """The setting in words."""
        if self.kind == REGION:
            return f"region {100 * self.fraction:g} %"
        return f"seed {self.seed}, {self.rows} x {self.columns}"


@dataclass(frozen=True)
class ClaimStability:
    """One exploration claim on the study's map and on every setting."""

    statement: str
    verdict: Verdict
    verdicts: tuple[Verdict, ...]

    @property
    def same(self) -> int:
        """Settings with the study map's verdict."""
        return sum(v == self.verdict for v in self.verdicts)

    def count(self, verdict: Verdict) -> int:
        """Settings with ``verdict``."""
        return sum(v == verdict for v in self.verdicts)


@dataclass(frozen=True)
class MapSensitivity:
    """A task's exploration numbers over the settings of one kind.

    Attributes:
        task: Task name.
        kind: :data:`MAP` or :data:`REGION`.
        treatments: Treatments, the order of the arrays' first axis.
        settings: The settings, the order of the arrays' second axis.
        on_map: (K,) each treatment's mean high-fitness share on the study's map.
        shares: (K, N) its mean high-fitness share on each setting.
        uniformity: (K, N) its mean uniformity on each setting.
        claims: Each exploration claim's verdicts (none off the paper's tasks).
    """

    task: str
    kind: str
    treatments: tuple[str, ...]
    settings: tuple[Setting, ...]
    on_map: np.ndarray
    shares: np.ndarray
    uniformity: np.ndarray
    claims: tuple[ClaimStability, ...]


def map_settings(maps: ExplorationMaps) -> list[Setting]:
    """The maps of other seeds and grids the digest holds (none without)."""
    found = maps.sensitivity
    if found is None:
        return []
    fraction = maps.settings.high_fitness_units
    return [
        Setting(
            MAP,
            seed,
            rows,
            columns,
            fraction,
            found.metrics(maps.task, maps.treatments, g, s),
        )
        for g, (rows, columns) in enumerate(found.grids)
        for s, seed in enumerate(found.seeds)
    ]


def region_settings(maps: ExplorationMaps) -> list[Setting]:
    """The study's map with each region size of :data:`REGION_FRACTIONS`."""
    s = maps.settings
    return [
        Setting(REGION, s.seed, s.rows, s.columns, f, maps.metrics(f))
        for f in REGION_FRACTIONS
    ]


def _verdicts(
    metrics: RunMetrics | ExplorationMaps, alpha: float
) -> dict[str, Verdict]:
    return {c.statement: c.verdict for c in exploration_claims(metrics, alpha)}


def sensitivity(
    maps: ExplorationMaps, kind: str, alpha: float = ALPHA
) -> MapSensitivity | None:
    """The task's numbers and verdicts over the settings of ``kind`` (None where
    the digest holds none of that kind)."""
    settings = tuple(map_settings(maps) if kind == MAP else region_settings(maps))
    if not settings:
        return None
    k = len(maps.treatments)
    shares = np.array(
        [[s.metrics.region_share(i).mean() for s in settings] for i in range(k)]
    )
    uniformity = np.array(
        [[s.metrics.uniformity(i).mean() for s in settings] for i in range(k)]
    )
    base = exploration_claims(maps, alpha)
    if kind == REGION:
        # The region's size moves the high-fitness shares only.
        base = [c for c in base if c.statistic == REGION_STATISTIC]
    per_setting = [_verdicts(s.metrics, alpha) for s in settings]
    claims = tuple(
        ClaimStability(
            c.statement,
            c.verdict,
            tuple(v.get(c.statement, Verdict.INCONCLUSIVE) for v in per_setting),
        )
        for c in base
    )
    return MapSensitivity(
        task=maps.task,
        kind=kind,
        treatments=maps.treatments,
        settings=settings,
        on_map=np.array([maps.region_share(i).mean() for i in range(k)]),
        shares=shares,
        uniformity=uniformity,
        claims=claims,
    )
