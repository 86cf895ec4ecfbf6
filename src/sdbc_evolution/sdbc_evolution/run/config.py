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
from dataclasses import field
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import yaml
from pydantic import BeforeValidator
from sdbc_sim.settings import (
    Field,
    NonNegativeInt,
    PositiveInt,
    SettingsError,
    check,
    load,
    settings,
    to_plain,
)
from sdbc_sim.yaml_input import YamlRefused, read_yaml

# GaConfig is the ask/tell object's (sdbc_evolution.ga.breeding); re-exported here
# as a section of the configuration.
from sdbc_evolution.ga.breeding import GaConfig as GaConfig
from sdbc_evolution.ga.novelty import NoveltyConfig
from sdbc_evolution.ga.treatments import PRESETS, TreatmentSpec, parse_treatment
from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings


class ConfigError(SettingsError):
    """A configuration that cannot run; the message names the offending key."""


PhysicsModel = Literal["rigid", "kinematic"]
"""The engine's physics models (``sdbc_sim.physics.MODELS``, checked by a test)."""
PHYSICS_MODELS: tuple[str, ...] = get_args(PhysicsModel)
"""Their names, for command lines."""
QUICKSTART_GENERATIONS = 40
"""Generations of the quick-start experiment."""
QUICKSTART_POPULATION = 50
"""Population of the quick-start experiment."""
QUICKSTART_REEVALUATION = 20
"""Re-evaluation trials of each generation's best in the quick-start experiment."""


@settings
class EvaluationConfig:
    """How individuals are evaluated."""

    trials: PositiveInt = 10
    """Trials per individual per generation, each with fresh initial conditions."""
    reevaluation_trials: NonNegativeInt = 50
    """Fresh trials in which each generation's best individual is re-evaluated for
    the reported curves; 0 disables re-evaluation."""
    fitness_mean: Literal["harmonic", "arithmetic"] = "harmonic"
    """How a controller's fitness sums up its trials: "harmonic" (the authors'
    code; trials under 1e-4 count as 1e-4) or "arithmetic"."""
    physics: PhysicsModel = "rigid"
    """How robots move and meet (``sdbc_sim.physics.PhysicsSettings.model``):
    "rigid" (pymunk rigid bodies; contacts go through chipmunk's solver, so robots
    push each other and slide along walls) or "kinematic" (the authors' robots: a
    move that would overlap is refused and retried sideways at half speed)."""


@settings
class ExperimentConfig:
    """One evolutionary run: a task, a treatment, the GA's settings and a seed."""

    task: Annotated[str, Field(min_length=1)] = "gate_escape"
    """The task: a registered name, ``package.module:Class`` or
    ``path/file.py:Class`` (made absolute here), see :mod:`sdbc_sim.tasks`."""
    task_config: dict[str, Any] = field(default_factory=dict)
    """Overrides of the task's own settings (checked against them by
    :func:`check_task_config`)."""
    treatment: Annotated[TreatmentSpec, BeforeValidator(parse_treatment)] = field(
        default_factory=lambda: PRESETS["ns-sd+"]
    )
    """What drives selection: a paper preset's name (``fit``, ``ns-ts``, ``ns-sd``,
    ``ns-sd+``) or a declared treatment (``sdbc_evolution.ga.treatments``)."""
    generations: PositiveInt | None = None
    """Generations to run; None takes the task's ``default_generations``."""
    seed: Annotated[int, Field(ge=0, lt=2**63)] = 0
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
        # A task in a file of one's own is named by its absolute path, so that
        # workers, nodes and a later resume find it from any directory.
        from sdbc_sim.tasks import task_reference

        object.__setattr__(self, "task", task_reference(self.task))
        # Novelty counts neighbours among the generation's other individuals
        # and the archive: a k that both together can never reach is a mistake.
        most = self.ga.population_size - 1 + self.novelty.archive_size
        check(
            self.novelty.k <= most,
            "novelty.k",
            f"{self.novelty.k} is more than the {most} neighbours a generation "
            f"can ever have (ga.population_size - 1 + novelty.archive_size)",
        )

    def notes(self) -> list[str]:
        """What the run does differently from what its settings may suggest, one
        line each, for the command line to say before the run starts."""
        others = self.ga.population_size - 1
        if self.treatment.characterisation is None or self.novelty.k <= others:
            return []  # no novelty (Fit), or k neighbours from the start
        return [
            f"novelty.k={self.novelty.k} is more than the {others} other "
            "individuals of a generation: novelty averages over all of them and "
            f"the archive until the archive holds {self.novelty.k - others} entries"
        ]

    @property
    def resolved_generations(self) -> int:
        """Generations to run, with the task's default filled in.

        Raises:
            ConfigError: ``generations`` is not set and the task names none of
                this project's tasks (a task another system runs).
        """
        if self.generations is not None:
            return self.generations
        from sdbc_sim.tasks import find_task

        task_class = find_task(self.task)
        if task_class is None:
            raise ConfigError(
                f"generations: task {self.task!r} is not one this project knows, so "
                "it has no default; set generations"
            )
        return task_class.default_generations

    def resolved(self) -> ExperimentConfig:
        """This configuration with every default filled in."""
        return dataclasses.replace(self, generations=self.resolved_generations)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (YAML-ready) for this configuration."""
        return to_plain(self)

    def replace(self, **changes: Any) -> ExperimentConfig:
        """A copy with top-level fields changed, validated again.

        Raises:
            ConfigError: Naming the bad field.
        """
        try:
            return dataclasses.replace(self, **changes)
        except SettingsError as error:
            raise _config_error(error) from None


def check_task_config(task: str, task_config: dict[str, Any]) -> None:
    """Checks ``task_config`` against the settings of ``task``.

    Raises:
        ConfigError: An unknown task, or a bad setting named as
            ``task_config.NAME``.
    """
    from sdbc_sim.tasks import UnknownTask, resolve_task, task_settings

    try:
        task_class = resolve_task(task)
    except UnknownTask as error:
        raise ConfigError(f"task: {error}") from None
    try:
        task_settings(task_class, task_config)
    except SettingsError as error:
        raise _config_error(error.prefixed("task_config")) from None


def quickstart_config() -> ExperimentConfig:
    """The small default experiment of the command line: NS-SD+ on gate escape,
    sized to finish in two to three minutes on two cores (the settings of
    docs/reference-setup.md otherwise).
    ``configs/quickstart.yaml`` holds the same values."""
    return ExperimentConfig(
        task="gate_escape",
        treatment=PRESETS["ns-sd+"],
        generations=QUICKSTART_GENERATIONS,
        ga=GaConfig(population_size=QUICKSTART_POPULATION),
        evaluation=EvaluationConfig(reevaluation_trials=QUICKSTART_REEVALUATION),
    )


def _config_error(error: SettingsError) -> ConfigError:
    return ConfigError(str(error), error.problems)


def config_from_dict(data: Any) -> ExperimentConfig:
    """Builds and validates an :class:`ExperimentConfig` from plain data.

    Raises:
        ConfigError: Naming every bad key by its dotted path.
    """
    try:
        return load(ExperimentConfig, data)
    except SettingsError as error:
        raise _config_error(error) from None


def load_config(path: str | Path) -> ExperimentConfig:
    """Reads an :class:`ExperimentConfig` from a YAML file.

    Raises:
        ConfigError: The file is missing, not YAML, or not a valid configuration.
    """
    path = Path(path)
    try:
        data = read_yaml(path, "configuration")
    except YamlRefused as error:
        raise ConfigError(str(error)) from None
    if data is None:
        # Not every default: an empty file is more likely a mistake than a wish
        # for a paper-scale run.
        raise ConfigError(
            f"{path} is empty: give at least the task (e.g. 'task: gate_escape'), "
            "or leave --config out for the quick start"
        )
    try:
        return config_from_dict(data)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None


def load_treatment(value: str | Path) -> TreatmentSpec:
    """A treatment from a paper preset's name or a YAML file declaring one (the
    mapping itself, or a file with a top-level ``treatment`` key).

    Raises:
        ConfigError: Neither a preset nor a readable declaration, naming the problem.
    """
    text = str(value)
    if text in PRESETS:
        return PRESETS[text]
    path = Path(text)
    if not path.is_file():
        raise ConfigError(
            f"treatment: {text!r} is neither a paper treatment ({list(PRESETS)}) nor "
            "a YAML file"
        )
    try:
        data = read_yaml(path, "treatment file")
    except YamlRefused as error:
        raise ConfigError(str(error)) from None
    if isinstance(data, dict) and set(data) == {"treatment"}:
        data = data["treatment"]
    try:
        return parse_treatment(data)
    except SettingsError as error:
        raise ConfigError(f"{path}: {error.prefixed('treatment')}") from None


def dump_config(config: ExperimentConfig) -> str:
    """The configuration as YAML text that :func:`load_config` reads back."""
    return yaml.safe_dump(config.to_dict(), sort_keys=False)
