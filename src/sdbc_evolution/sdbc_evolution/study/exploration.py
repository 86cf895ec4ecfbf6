"""Behaviour-space exploration: the paper's Kohonen maps (self-organising maps).

Per task, as in the authors' analysis scripts:

1. a **sample** of raw SDBC vectors drawn evenly from every run of every treatment
   (individuals of all generations), z-scored per dimension with the sample's mean
   and SD (SD 0 read as 1);
2. a ``rows x columns`` **SOM** (minisom; weights start at random sample vectors,
   Gaussian neighbourhood) trained on that sample;
3. every individual of every run **mapped** to its best-matching unit
   BMU(x) = argmin_u ||z(x) - m_u||;
4. per run, the **share** of its individuals in each unit, s_{r,u} = n_{r,u} / n_r
   (sum over u = 1); per treatment, the mean share over its runs (circle size), and
   the ``fitness_percentile``-th percentile of the fitness of its individuals in each
   unit, pooled over its runs (colour).

Two per-run numbers put the paper's reading of the maps to a test:

- **uniformity**: the normalised entropy of the run's shares,
  U_r = -sum_u s_{r,u} ln s_{r,u} / ln(rows x columns), 1 when every unit holds as
  many individuals, 0 when one unit holds them all ("Fit explores a narrow region",
  "NS-SD is the most uniform");
- **high-fitness share**: the share of the run's individuals in the high-fitness
  region, the ``high_fitness_units`` fraction of occupied units with the highest
  pooled (all treatments) fitness percentile (:func:`high_fitness_region`; "NS-SD+
  spends more effort in the high-fitness region than NS-SD"); where the task
  declares a deceptive optimum (:func:`sdbc_evolution.study.paper.deceptive_optimum`:
  resource sharing's no-charge optimum), only units whose percentile lies above it
  (in the first local study the top 10 % began at 0.1429, below the no-charge
  optimum 0.1446, so the region marked the teams that never charge and Fit had
  the largest share).

The maps depend on the SOM's seed and grid. :func:`exploration_sensitivity` trains
the task's map again for several seeds and grids (from the run directories, with one
pass to sample and one to map) and keeps each run's uniformity and high-fitness share
on every one of them (:class:`Sensitivity`), which the digest stores beside the map
when the analysis asked for it. A digest without them (the SDBC vectors are not
kept) can still vary the region's size on its one map (:data:`REGION_FRACTIONS`,
:meth:`ExplorationMaps.metrics`); :mod:`.sensitivity` judges the claims on each.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from sdbc_evolution.study.paper import deceptive_optimum
from sdbc_evolution.study.rundirs import RunData, StudyData

BMU_CHUNK = 4096
"""Individuals mapped per matrix product (bounds the memory of the mapping)."""
REGION_FRACTIONS = (0.05, 0.1, 0.2)
"""Sizes of the high-fitness region (fractions of the occupied units) over which a
digest's one map is re-read: the sensitivity the digest alone can measure."""
GRID_SCALES = (0.5, 0.75, 1.0)
"""The grids of a sensitivity analysis by default: the map's rows and columns
scaled by these (20 x 20: 10 x 10, 15 x 15, 20 x 20)."""


@dataclass(frozen=True)
class SomSettings:
    """The exploration maps."""

    rows: int = 20
    """Rows of the map (the paper: 20)."""
    columns: int = 20
    """Columns of the map (the paper: 20)."""
    sample_size: int = 50_000
    """SDBC vectors the map is trained on (the authors' scripts: 50 000)."""
    iterations: int = 50_000
    """Training steps (one sample vector each)."""
    sigma: float = 3.0
    """Initial neighbourhood radius, in units; it decays as training goes."""
    learning_rate: float = 0.5
    """Initial learning rate; it decays as training goes."""
    fitness_percentile: float = 75.0
    """Percentile of the fitness in a unit that colours it (the authors: 75)."""
    high_fitness_units: float = 0.1
    """Fraction of the occupied units that make up the high-fitness region."""
    seed: int = 0
    """Seed of the sample and the map's training."""

    def __post_init__(self) -> None:
        checks = {
            "rows": self.rows >= 2,
            "columns": self.columns >= 2,
            "sample_size": self.sample_size >= 2,
            "iterations": self.iterations >= 1,
            "sigma": self.sigma > 0,
            "learning_rate": self.learning_rate > 0,
            "fitness_percentile": 0 <= self.fitness_percentile <= 100,
            "high_fitness_units": 0 < self.high_fitness_units <= 1,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"SOM settings out of range: {', '.join(bad)}")

    @property
    def units(self) -> int:
        """Units of the map: rows x columns."""
        return self.rows * self.columns


class MapNumbers(Protocol):
    """Per-run numbers of a map, per treatment: what the exploration claims test."""

    @property
    def task(self) -> str:
        """Task name."""
        ...

    @property
    def treatments(self) -> tuple[str, ...]:
        """Treatments, the order of ``k``."""
        ...

    def uniformity(self, k: int) -> np.ndarray:
        """(R,) normalised entropy of each run of treatment ``k``."""
        ...

    def region_share(self, k: int) -> np.ndarray:
        """(R,) share of each run of treatment ``k`` in the high-fitness region."""
        ...


@dataclass(frozen=True)
class RunMetrics:
    """Each run's uniformity and high-fitness share on one map (of the
    treatments in order), without the map."""

    task: str
    treatments: tuple[str, ...]
    uniformities: tuple[np.ndarray, ...]
    region_shares: tuple[np.ndarray, ...]

    def uniformity(self, k: int) -> np.ndarray:
        """(R,) normalised entropy of each run of treatment ``k``."""
        return self.uniformities[k]

    def region_share(self, k: int) -> np.ndarray:
        """(R,) share of each run of treatment ``k`` in the high-fitness region."""
        return self.region_shares[k]


@dataclass(frozen=True)
class Sensitivity:
    """Every run's numbers on maps trained with other seeds and grids.

    Attributes:
        seeds: (S,) the maps' seeds (of the sample and the training).
        grids: (G,) the maps' (rows, columns).
        uniformity: Per treatment (in the maps' order), (G, S, R) each run's
            uniformity on each map.
        region_share: The same for its share in the high-fitness region.
    """

    seeds: tuple[int, ...]
    grids: tuple[tuple[int, int], ...]
    uniformity: tuple[np.ndarray, ...]
    region_share: tuple[np.ndarray, ...]

    def metrics(
        self, task: str, treatments: tuple[str, ...], g: int, s: int
    ) -> RunMetrics:
        """The runs' numbers on the map of grid ``g`` and seed ``s`` (indices)."""
        return RunMetrics(
            task,
            treatments,
            tuple(u[g, s] for u in self.uniformity),
            tuple(h[g, s] for h in self.region_share),
        )


@dataclass(frozen=True)
class ExplorationMaps:
    """The maps of one task: what the figures, tables and claims need of the SOM,
    all of it small (the SOM's weights and the individuals are not kept).

    Attributes:
        task: Task name.
        settings: How they were made.
        treatments: Treatments, the order of every per-treatment axis.
        run_names: Per treatment, its runs' names.
        counts: Per treatment, (R, U) int64 individuals of each run per unit.
        percentile: (K, U) fitness percentile of the treatment's individuals per
            unit (NaN where it has none).
        pooled_percentile: (U,) the same over every treatment's individuals.
        sample_count: SDBC vectors the map was trained on.
        quantisation_error: Mean distance of the sample to its BMU's weights.
        sensitivity: The runs' numbers on maps of other seeds and grids, or
            None (not computed).
    """

    task: str
    settings: SomSettings
    treatments: tuple[str, ...]
    run_names: tuple[tuple[str, ...], ...]
    counts: tuple[np.ndarray, ...]
    percentile: np.ndarray
    pooled_percentile: np.ndarray
    sample_count: int
    quantisation_error: float
    sensitivity: Sensitivity | None = None

    @property
    def shares(self) -> tuple[np.ndarray, ...]:
        """Per treatment, (R, U) share of each run's individuals per unit."""
        return tuple(c / c.sum(axis=1, keepdims=True) for c in self.counts)

    @property
    def mean_share(self) -> np.ndarray:
        """(K, U) mean share over the treatment's runs."""
        return np.stack([s.mean(axis=0) for s in self.shares])

    @property
    def region(self) -> np.ndarray:
        """(U,) bool, the high-fitness region (:func:`high_fitness_region`)."""
        return self.region_of(self.settings.high_fitness_units)

    def region_of(self, fraction: float) -> np.ndarray:
        """(U,) bool, the high-fitness region of ``fraction`` of the occupied
        units."""
        return high_fitness_region(
            self.pooled_percentile, fraction, deceptive_optimum(self.task)
        )

    def metrics(self, fraction: float | None = None) -> RunMetrics:
        """The runs' uniformity and high-fitness share, the region made of
        ``fraction`` of the occupied units (None: the settings' own)."""
        region = self.region if fraction is None else self.region_of(fraction)
        return RunMetrics(
            self.task,
            self.treatments,
            tuple(self.uniformity(k) for k in range(len(self.treatments))),
            tuple(s[:, region].sum(axis=1) for s in self.shares),
        )

    def uniformity(self, k: int) -> np.ndarray:
        """(R,) normalised entropy of each run of treatment ``k``."""
        return _uniformity(self.counts[k], self.settings.units)

    def region_share(self, k: int) -> np.ndarray:
        """(R,) share of each run of treatment ``k`` in the high-fitness region."""
        return self.shares[k][:, self.region].sum(axis=1)

    def coverage(self, k: int) -> np.ndarray:
        """(R,) fraction of the units each run of treatment ``k`` visits."""
        return (self.shares[k] > 0).mean(axis=1)


def _samples(
    runs: list[RunData], size: int, rngs: Sequence[np.random.Generator]
) -> list[np.ndarray]:
    """Per generator, about ``size`` raw SDBC vectors, the same number from every
    run; one pass over the runs for all of them (each generator draws as it
    would alone)."""
    per_run = max(1, size // len(runs))
    parts: list[list[np.ndarray]] = [[] for _ in rngs]
    for run in runs:
        counts = np.array([f.shape[0] for f in run.fitness])
        total = int(counts.sum())
        chosen = [
            np.sort(rng.choice(total, size=min(per_run, total), replace=False))
            for rng in rngs
        ]
        offsets = np.concatenate([[0], np.cumsum(counts)])
        for g, sdbc in enumerate(run.sdbc_generations()):
            for picked, out in zip(chosen, parts, strict=True):
                lo, hi = np.searchsorted(picked, offsets[g : g + 2])
                if hi > lo:
                    out.append(sdbc[picked[lo:hi] - offsets[g]].astype(np.float64))
    return [np.concatenate(p) for p in parts]


def best_matching_units(weights: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(n,) index of the nearest unit of ``weights`` (U, D) to each row of ``z``."""
    norms = np.einsum("ud,ud->u", weights, weights)
    out = np.empty(z.shape[0], dtype=np.int64)
    for start in range(0, z.shape[0], BMU_CHUNK):
        block = z[start : start + BMU_CHUNK]
        distance = norms[None, :] - 2.0 * block @ weights.T
        out[start : start + BMU_CHUNK] = np.argmin(distance, axis=1)
    return out


class _Scaler:
    """z = (x - mean) / sd with the sample's coefficients (SD 0 read as 1)."""

    def __init__(self, sample: np.ndarray) -> None:
        self.mean = sample.mean(axis=0)
        sd = sample.std(axis=0)
        self.sd = np.where(sd > 0, sd, 1.0)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        z = (np.asarray(x, dtype=np.float64) - self.mean) / self.sd
        # Non-finite values sit at the mean, as the authors' 0.5 fill did.
        return np.where(np.isfinite(z), z, 0.0)


def _percentiles(
    units: np.ndarray, fitness: np.ndarray, n_units: int, q: float
) -> np.ndarray:
    out = np.full(n_units, np.nan)
    order = np.argsort(units, kind="stable")
    units, fitness = units[order], fitness[order]
    bounds = np.searchsorted(units, np.arange(n_units + 1))
    for u in range(n_units):
        if bounds[u + 1] > bounds[u]:
            out[u] = np.percentile(fitness[bounds[u] : bounds[u + 1]], q)
    return out


def high_fitness_region(
    pooled: np.ndarray, fraction: float, floor: float | None = None
) -> np.ndarray:
    """(U,) bool: the ``fraction`` of occupied units with the highest ``pooled``
    percentile, ties with the last one included, units at the lowest percentile
    never (if every occupied unit ties, there is no high-fitness region), nor
    units at or below ``floor`` (a deceptive optimum: fewer units, or none)."""
    occupied = pooled[np.isfinite(pooled)]
    region = np.zeros(pooled.shape, dtype=bool)
    if occupied.size == 0:
        return region
    n = max(1, int(round(fraction * occupied.size)))
    threshold = np.sort(occupied)[::-1][n - 1]
    with np.errstate(invalid="ignore"):
        region[:] = (pooled >= threshold) & (pooled > occupied.min())
        if floor is not None:
            region &= pooled > floor
    return region


def _train(sample: np.ndarray, settings: SomSettings) -> np.ndarray:
    """(U, D) weights of a map trained on the z-scored ``sample``."""
    from minisom import MiniSom

    som = MiniSom(
        settings.rows,
        settings.columns,
        sample.shape[1],
        sigma=settings.sigma,
        learning_rate=settings.learning_rate,
        random_seed=settings.seed,
    )
    som.random_weights_init(sample)
    som.train(sample, settings.iterations, random_order=True)
    return np.asarray(som.get_weights()).reshape(settings.units, -1)


def _uniformity(counts: np.ndarray, units: int) -> np.ndarray:
    """(R,) normalised entropy of each row of ``counts`` (R, U)."""
    s = counts / counts.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(s > 0, s * np.log(s), 0.0)
    return np.asarray(-terms.sum(axis=1) / np.log(units))


def exploration_maps(
    study: StudyData, task: str, settings: SomSettings | None = None
) -> ExplorationMaps:
    """Trains the task's map and maps every run onto it (see module docstring)."""
    settings = settings or SomSettings()
    treatments = tuple(study.treatments(task))
    runs = study.of(task)
    rng = np.random.default_rng(settings.seed)
    raw = _samples(runs, settings.sample_size, [rng])[0]
    scaler = _Scaler(raw)
    sample = scaler(raw)
    weights = _train(sample, settings)
    sample_units = best_matching_units(weights, sample)
    quantisation_error = float(
        np.linalg.norm(sample - weights[sample_units], axis=1).mean()
    )
    counts, names, unit_lists, fitness_lists = [], [], [], []
    for treatment in treatments:
        treatment_runs = study.of(task, treatment)
        run_counts, run_units, run_fitness = [], [], []
        for run in treatment_runs:
            units = np.concatenate(
                [
                    best_matching_units(weights, scaler(x))
                    for x in run.sdbc_generations()
                ]
            )
            run_counts.append(np.bincount(units, minlength=settings.units))
            run_units.append(units)
            run_fitness.append(np.concatenate(run.fitness))
        counts.append(np.stack(run_counts).astype(np.int64))
        names.append(tuple(r.name for r in treatment_runs))
        unit_lists.append(np.concatenate(run_units))
        fitness_lists.append(np.concatenate(run_fitness))
    q = settings.fitness_percentile
    percentile = np.stack(
        [
            _percentiles(u, f, settings.units, q)
            for u, f in zip(unit_lists, fitness_lists, strict=True)
        ]
    )
    pooled = _percentiles(
        np.concatenate(unit_lists), np.concatenate(fitness_lists), settings.units, q
    )
    return ExplorationMaps(
        task=task,
        settings=settings,
        treatments=treatments,
        run_names=tuple(names),
        counts=tuple(counts),
        percentile=percentile,
        pooled_percentile=pooled,
        sample_count=int(sample.shape[0]),
        quantisation_error=quantisation_error,
    )


def default_grids(settings: SomSettings) -> tuple[tuple[int, int], ...]:
    """The grids of a sensitivity analysis of maps made with ``settings``: its
    rows and columns scaled by :data:`GRID_SCALES` (at least 2 x 2)."""
    return tuple(
        dict.fromkeys(
            (max(2, round(settings.rows * f)), max(2, round(settings.columns * f)))
            for f in GRID_SCALES
        )
    )


def exploration_sensitivity(
    study: StudyData,
    task: str,
    settings: SomSettings,
    seeds: Sequence[int],
    grids: Sequence[tuple[int, int]],
) -> Sensitivity:
    """Each run's uniformity and high-fitness share on the task's map trained
    again with every seed of ``seeds`` and grid of ``grids``, the other settings
    ``settings``' (the map of ``settings``' own seed and grid is the one
    :func:`exploration_maps` makes). Two passes over the runs' SDBC vectors
    whatever the number of maps; every individual's unit on every map is held
    at once (2 bytes each, up to 32768 units)."""
    if not seeds or not grids:
        raise ValueError("a sensitivity analysis needs at least one seed and grid")
    treatments = tuple(study.treatments(task))
    runs = [r for t in treatments for r in study.of(task, t)]
    raws = _samples(
        study.of(task),
        settings.sample_size,
        [np.random.default_rng(seed) for seed in seeds],
    )
    scalers = [_Scaler(raw) for raw in raws]
    maps = [
        [
            _train(
                scaler(raw),
                replace(settings, rows=rows, columns=columns, seed=seed),
            )
            for seed, scaler, raw in zip(seeds, scalers, raws, strict=True)
        ]
        for rows, columns in grids
    ]
    counts = [
        [np.zeros((len(runs), rows * columns), dtype=np.int64) for _ in seeds]
        for rows, columns in grids
    ]
    units: list[list[list[np.ndarray]]] = [[[] for _ in seeds] for _ in grids]
    small = np.int16 if max(r * c for r, c in grids) <= 2**15 else np.int64
    fitness = []
    for i, run in enumerate(runs):
        for sdbc in run.sdbc_generations():
            for s, scaler in enumerate(scalers):
                z = scaler(sdbc)
                for g in range(len(grids)):
                    found = best_matching_units(maps[g][s], z)
                    counts[g][s][i] += np.bincount(
                        found, minlength=counts[g][s].shape[1]
                    )
                    units[g][s].append(found.astype(small))
        fitness.append(np.concatenate(run.fitness))
    pooled_fitness = np.concatenate(fitness)
    floor = deceptive_optimum(task)
    uniformity = np.empty((len(grids), len(seeds), len(runs)))
    share = np.empty_like(uniformity)
    for g, (rows, columns) in enumerate(grids):
        for s in range(len(seeds)):
            pooled = _percentiles(
                np.concatenate(units[g][s]).astype(np.int64),
                pooled_fitness,
                rows * columns,
                settings.fitness_percentile,
            )
            units[g][s] = []
            region = high_fitness_region(pooled, settings.high_fitness_units, floor)
            c = counts[g][s]
            uniformity[g, s] = _uniformity(c, rows * columns)
            share[g, s] = c[:, region].sum(axis=1) / c.sum(axis=1)
    bounds = np.cumsum([0] + [len(study.of(task, t)) for t in treatments])
    return Sensitivity(
        seeds=tuple(int(x) for x in seeds),
        grids=tuple((int(r), int(c)) for r, c in grids),
        uniformity=tuple(
            uniformity[:, :, lo:hi]
            for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)
        ),
        region_share=tuple(
            share[:, :, lo:hi] for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)
        ),
    )
