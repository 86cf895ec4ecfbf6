"""Typed configuration of an evolutionary experiment, loaded from YAML.

Every number of the "Evolution" section of docs/reference-setup.md is a default
here, in one place. A YAML file mirrors the dataclasses (sections ``ga``, ``novelty``,
``standardisation``, ``weighting``, ``evaluation``, plus top-level ``task``,
``task_config``, ``treatment``, ``generations`` and ``seed``); keys left out keep their
defaults. Unknown keys, wrong types and out-of-range values raise :class:`ConfigError`
naming the key, before any work runs.

Example::

    task: resource_sharing
    treatment: ns-sd+
    seed: 3
    ga: {population_size: 50}
    evaluation: {trials: 5}
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

import yaml

from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings


class ConfigError(ValueError):
    """A configuration that cannot run; the message names the offending key."""


class Treatment(str, Enum):
    """The paper's four evolutionary treatments."""

    FIT = "fit"
    """Fitness-driven evolution: rank on fitness alone."""
    NS_TS = "ns-ts"
    """Novelty search (+ fitness) with the task-specific characterisation."""
    NS_SD = "ns-sd"
    """Novelty search (+ fitness) with the SDBC, unweighted."""
    NS_SD_PLUS = "ns-sd+"
    """Novelty search (+ fitness) with the SDBC, weighted by mutual information."""


DEFAULT_GENERATIONS: dict[str, int] = {
    "gate_escape": 500,
    "resource_sharing": 750,
    "predator_prey": 750,
}
"""Generations per task in the paper's runs (docs/reference-setup.md); other tasks
must set ``generations`` explicitly."""


QUICKSTART_GENERATIONS = 40
"""Generations of the quick-start experiment."""
QUICKSTART_POPULATION = 50
"""Population of the quick-start experiment."""
QUICKSTART_REEVALUATION = 20
"""Re-evaluation trials of each generation's best in the quick-start experiment."""


@dataclass(frozen=True)
class GaConfig:
    """The generational GA."""

    population_size: int = 200
    """Individuals per generation."""
    tournament_size: int = 5
    """Contestants per tournament when choosing a parent."""
    elites: int = 5
    """Best individuals copied unchanged into the next generation (and evaluated
    again there in fresh trials)."""
    mutation_sigma: float = 0.5
    """Standard deviation of the Gaussian perturbation of a mutating gene."""
    mutation_probability: float = 0.05
    """Chance that each gene mutates."""
    gene_min: float = -1.0
    """Lower bound of every gene (network weight)."""
    gene_max: float = 1.0
    """Upper bound of every gene."""
    max_redraws: int = 100
    """Out-of-bounds mutation draws allowed per gene before a uniform value in the
    bounds is taken instead (ECJ's default)."""

    def __post_init__(self) -> None:
        _check(self.population_size >= 2, "ga.population_size", "must be at least 2")
        _check(
            1 <= self.tournament_size <= self.population_size,
            "ga.tournament_size",
            f"must be in [1, population_size={self.population_size}]",
        )
        _check(
            0 <= self.elites < self.population_size,
            "ga.elites",
            f"must be in [0, population_size={self.population_size})",
        )
        _check(
            math.isfinite(self.mutation_sigma) and self.mutation_sigma > 0,
            "ga.mutation_sigma",
            "must be positive",
        )
        _check(
            0.0 <= self.mutation_probability <= 1.0,
            "ga.mutation_probability",
            "must be in [0, 1]",
        )
        _check(
            math.isfinite(self.gene_min)
            and math.isfinite(self.gene_max)
            and self.gene_min < self.gene_max,
            "ga.gene_min",
            f"must be finite and below ga.gene_max={self.gene_max}",
        )
        _check(self.max_redraws >= 1, "ga.max_redraws", "must be at least 1")


@dataclass(frozen=True)
class NoveltyConfig:
    """The novelty metric, its archive and the (fitness, novelty) ranking."""

    k: int = 15
    """Nearest neighbours averaged by the novelty metric."""
    archive_probability: float = 0.03
    """Chance that each evaluated individual enters the archive."""
    archive_size: int = 1000
    """Most archive entries; a random one is replaced when full."""
    tie_break: str = "crowding"
    """Order inside a non-dominated front: "crowding" (NSGA-II crowding distance,
    the paper) or "fitness" (fitness normalised within the front, the authors'
    code)."""

    def __post_init__(self) -> None:
        _check(self.k >= 1, "novelty.k", "must be at least 1")
        _check(
            0.0 <= self.archive_probability <= 1.0,
            "novelty.archive_probability",
            "must be in [0, 1]",
        )
        _check(self.archive_size >= 0, "novelty.archive_size", "must be >= 0")
        _check(
            self.tie_break in ("crowding", "fitness"),
            "novelty.tie_break",
            "must be 'crowding' or 'fitness'",
        )


@dataclass(frozen=True)
class EvaluationConfig:
    """How individuals are evaluated."""

    trials: int = 10
    """Trials per individual per generation, each with fresh initial conditions."""
    reevaluation_trials: int = 50
    """Fresh trials in which each generation's best individual is re-evaluated for
    the reported curves; 0 disables re-evaluation."""
    fitness_mean: str = "harmonic"
    """How a controller's fitness sums up its trials: "harmonic" (the authors'
    code; trials under 1e-4 count as 1e-4) or "arithmetic"."""

    def __post_init__(self) -> None:
        _check(self.trials >= 1, "evaluation.trials", "must be at least 1")
        _check(
            self.fitness_mean in ("harmonic", "arithmetic"),
            "evaluation.fitness_mean",
            "must be 'harmonic' or 'arithmetic'",
        )
        _check(
            self.reevaluation_trials >= 0,
            "evaluation.reevaluation_trials",
            "must be >= 0",
        )


@dataclass(frozen=True)
class ExperimentConfig:
    """One evolutionary run: a task, a treatment, the GA's settings and a seed."""

    task: str = "gate_escape"
    """Task name in the ``sdbc_sim.tasks`` registry."""
    task_config: dict[str, Any] = field(default_factory=dict)
    """Overrides of the task's own configuration (passed to ``make_task``)."""
    treatment: Treatment = Treatment.NS_SD_PLUS
    """Which of the four treatments drives selection."""
    generations: int | None = None
    """Generations to run; None takes the task's default from
    :data:`DEFAULT_GENERATIONS`."""
    seed: int = 0
    """Seed of the run: everything the run does is a function of (config, seed)."""
    ga: GaConfig = field(default_factory=GaConfig)
    """The GA."""
    novelty: NoveltyConfig = field(default_factory=NoveltyConfig)
    """Novelty metric, archive and ranking."""
    standardisation: StandardisationSettings = field(
        default_factory=StandardisationSettings
    )
    """SDBC standardisation (NS-SD, NS-SD+): clip, SD estimator."""
    weighting: WeightingSettings = field(default_factory=WeightingSettings)
    """NS-SD+ weights: delta, discretisation, how often they are recomputed."""
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    """Trials and re-evaluation."""

    def __post_init__(self) -> None:
        _check(bool(self.task), "task", "must name a task")
        try:
            object.__setattr__(self, "treatment", Treatment(self.treatment))
        except ValueError:
            raise ConfigError(
                f"treatment: {self.treatment!r} is not one of "
                f"{[t.value for t in Treatment]}"
            ) from None
        _check(isinstance(self.task_config, dict), "task_config", "must be a mapping")
        if self.generations is not None:
            _check(self.generations >= 1, "generations", "must be at least 1")
        _check(0 <= self.seed < 2**63, "seed", "must be in [0, 2^63)")

    @property
    def resolved_generations(self) -> int:
        """Generations to run, with the task's default filled in."""
        if self.generations is not None:
            return self.generations
        if self.task not in DEFAULT_GENERATIONS:
            raise ConfigError(
                f"generations: task {self.task!r} has no default; set it explicitly"
            )
        return DEFAULT_GENERATIONS[self.task]

    def resolved(self) -> ExperimentConfig:
        """This configuration with every default filled in."""
        return dataclasses.replace(self, generations=self.resolved_generations)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (YAML-ready) for this configuration."""
        return _to_plain(self)

    def replace(self, **changes: Any) -> ExperimentConfig:
        """A copy with top-level fields changed, validated again."""
        return dataclasses.replace(self, **changes)


def quickstart_config() -> ExperimentConfig:
    """The small default experiment of the command line: NS-SD+ on gate escape,
    sized to finish in two to three minutes on two cores (the settings of
    docs/reference-setup.md otherwise).
    ``configs/quickstart.yaml`` holds the same values."""
    return ExperimentConfig(
        task="gate_escape",
        treatment=Treatment.NS_SD_PLUS,
        generations=QUICKSTART_GENERATIONS,
        ga=GaConfig(population_size=QUICKSTART_POPULATION),
        evaluation=EvaluationConfig(reevaluation_trials=QUICKSTART_REEVALUATION),
    )


def _check(ok: bool, key: str, message: str) -> None:
    if not ok:
        raise ConfigError(f"{key}: {message}")


def _to_plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value):
        return {
            f.name: _to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)
        }
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, dict):
        return {str(k): _to_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_to_plain(v) for v in value]
    return value


def _coerce(value: Any, annotation: Any, key: str) -> Any:
    """Checks one YAML value against a field's type; returns it converted."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(annotation)
        if value is None and type(None) in options:
            return None
        last: ConfigError | None = None
        for option in options:
            if option is type(None):
                continue
            try:
                return _coerce(value, option, key)
            except ConfigError as error:
                last = error
        assert last is not None
        raise last
    if origin is typing.Literal:
        allowed = typing.get_args(annotation)
        if value not in allowed:
            raise ConfigError(f"{key}: {value!r} is not one of {list(allowed)}")
        return value
    if dataclasses.is_dataclass(annotation):
        return _from_mapping(annotation, value, key)
    if isinstance(annotation, type) and issubclass(annotation, Enum):
        try:
            return annotation(value)
        except ValueError:
            raise ConfigError(
                f"{key}: {value!r} is not one of {[e.value for e in annotation]}"
            ) from None
    if annotation is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key}: expected true or false, got {value!r}")
        return value
    if annotation is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key}: expected an integer, got {value!r}")
        return value
    if annotation is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{key}: expected a finite number, got {value!r}")
        return float(value)
    if annotation is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a string, got {value!r}")
        return value
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{key}: expected a mapping, got {value!r}")
        return dict(value)
    raise ConfigError(f"{key}: unsupported field type {annotation!r}")


def _from_mapping(cls: type, data: Any, prefix: str) -> Any:
    if data is None:
        data = {}
    where = prefix or "configuration"
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(str(k) for k in data if k not in names)
    if unknown:
        dotted = [f"{prefix}.{k}" if prefix else k for k in unknown]
        raise ConfigError(
            f"unknown key(s) {dotted}; known keys of {where}: {sorted(names)}"
        )
    values = {}
    for name, value in data.items():
        key = f"{prefix}.{name}" if prefix else name
        values[name] = _coerce(value, hints[name], key)
    try:
        return cls(**values)
    except ConfigError:
        raise
    except (TypeError, ValueError) as error:
        message = str(error)
        if not message.startswith(f"{where}:"):
            message = f"{where}: {message}"
        raise ConfigError(message) from None


def config_from_dict(data: Any) -> ExperimentConfig:
    """Builds and validates an :class:`ExperimentConfig` from plain data."""
    return _from_mapping(ExperimentConfig, data, "")


def load_config(path: str | Path) -> ExperimentConfig:
    """Reads an :class:`ExperimentConfig` from a YAML file.

    Raises:
        ConfigError: The file is missing, not YAML, or not a valid configuration.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ConfigError(f"cannot read configuration {path}: {error}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ConfigError(f"{path} is not valid YAML: {error}") from None
    try:
        return config_from_dict(data)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None


def dump_config(config: ExperimentConfig) -> str:
    """The configuration as YAML text that :func:`load_config` reads back."""
    return yaml.safe_dump(config.to_dict(), sort_keys=False)
