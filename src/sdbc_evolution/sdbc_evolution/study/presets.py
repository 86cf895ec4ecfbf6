"""Study presets: which tasks, treatments and runs a replication study holds, and
the sizes of its runs.

A preset is a YAML file (``configs/study/NAME.yaml``) mirroring :class:`StudyPreset`;
keys left out keep the paper's values (docs/reference-setup.md), which are the
dataclass defaults here and in :mod:`sdbc_evolution.run.config`. Every run of the study
is an :class:`~sdbc_evolution.run.config.ExperimentConfig` built from the preset's
``experiment`` section (the same schema as an ``sdbc-evolve`` configuration, without
the keys the study sets itself), the task's generations and task settings, the
treatment and a seed of its own. Bad presets raise :class:`PresetError` naming the
key, before any run starts.

Example::

    name: mini
    runs: 3
    tasks: [gate_escape]
    generations: {gate_escape: 20}
    experiment:
      ga: {population_size: 20}
      evaluation: {trials: 3, reevaluation_trials: 10}
"""

from __future__ import annotations

from dataclasses import field
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import BeforeValidator
from sdbc_sim.settings import (
    Field,
    PositiveInt,
    SettingsError,
    check,
    load,
    settings,
    to_plain,
)
from sdbc_sim.yaml_input import YamlRefused, read_yaml

from sdbc_evolution.ga.treatments import PRESETS, TreatmentSpec, parse_treatment
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    check_task_config,
    config_from_dict,
)
from sdbc_evolution.study.champions import MIN_CHAMPION_TRIALS
from sdbc_evolution.study.paper import PAPER_TASKS
from sdbc_evolution.study.predictions import Prediction

PRESET_DIR = Path("configs") / "study"
"""Where the named presets live, relative to the repository root."""
PRESET_NAMES = ("smoke", "local", "paper", "local_new_tasks")
"""The presets shipped with the project (``local_new_tasks``: the tasks beyond the
paper at the ``local`` scale)."""
PAPER_RUNS = 20
"""Runs per treatment and task in the paper."""
STUDY_KEYS = ("task", "treatment", "seed", "generations", "task_config")
"""Experiment keys the study sets per run, so a preset's ``experiment`` may not."""


class PresetError(SettingsError):
    """A preset that cannot run; the message names the offending key."""


@settings
class StudyPreset:
    """A replication study: tasks x treatments x runs, and the settings of each run."""

    name: Annotated[str, Field(min_length=1)]
    """Name of the preset (``smoke``, ``local``, ``paper`` or a user's own)."""
    description: str = ""
    """What the preset is for, in a sentence or two."""
    runs: PositiveInt = PAPER_RUNS
    """Independent runs per treatment and task."""
    seed: Annotated[int, Field(ge=0, lt=2**63)] = 0
    """Study seed: every run's seed derives from it, its task, treatment and index."""
    tasks: Annotated[tuple[str, ...], Field(min_length=1)] = PAPER_TASKS
    """Tasks of the study, in the order they run: registered names or
    ``package.module:Class`` references (see :mod:`sdbc_sim.tasks`)."""
    treatments: Annotated[
        tuple[Annotated[TreatmentSpec, BeforeValidator(parse_treatment)], ...],
        Field(min_length=1),
    ] = tuple(PRESETS.values())
    """Treatments compared on every task: paper presets by name, or declared ones
    (mappings, as ``sdbc-evolve --treatment`` takes them)."""
    predictions: tuple[Prediction, ...] = ()
    """What the study is expected to show, judged by its analysis (see
    :mod:`sdbc_evolution.study.predictions`); they decide nothing about the runs."""
    generations: dict[str, PositiveInt] = field(default_factory=dict)
    """Generations per task; a task left out takes its ``default_generations``."""
    task_config: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Settings of each task that differ from its defaults."""
    experiment: dict[str, Any] = field(default_factory=dict)
    """Settings shared by every run (sections ``ga``, ``novelty``, ``evaluation``,
    ...; an ``sdbc-evolve`` configuration without the keys in :data:`STUDY_KEYS`)."""
    champion_trials: Annotated[int, Field(ge=0)] = 0
    """Trials each run's champion and last best are re-evaluated in once the run
    is done (0: not at all; else at least ``MIN_CHAMPION_TRIALS``; see
    :mod:`sdbc_evolution.study.champions`)."""

    def __post_init__(self) -> None:
        check(len(set(self.tasks)) == len(self.tasks), "tasks", "has duplicates")
        from sdbc_sim.tasks import is_file_reference

        # Run folders and reports are named after the task reference.
        files = [t for t in self.tasks if is_file_reference(t)]
        check(
            not files,
            "tasks",
            f"{files}: a study names its tasks by a registered name or "
            "package.module:Class, not by a file (register the task as an entry "
            "point, or put its folder on PYTHONPATH)",
        )
        check(
            len({t.name for t in self.treatments}) == len(self.treatments),
            "treatments",
            f"has duplicates: {[t.name for t in self.treatments]}",
        )
        check(
            len({t.directory for t in self.treatments}) == len(self.treatments),
            "treatments",
            f"names that share a directory: {[t.name for t in self.treatments]}",
        )
        names = {t.name for t in self.treatments}
        for k, prediction in enumerate(self.predictions):
            for side in ("a", "b"):
                check(
                    getattr(prediction, side) in names,
                    f"predictions.{k}.{side}",
                    f"{getattr(prediction, side)!r} is not a treatment of the study "
                    f"({sorted(names)})",
                )
            check(
                prediction.a != prediction.b,
                f"predictions.{k}",
                "compares a treatment with itself",
            )
            extra = sorted(set(prediction.tasks) - set(self.tasks))
            check(not extra, f"predictions.{k}.tasks", f"not in the study: {extra}")
        for key in ("generations", "task_config"):
            extra = sorted(set(getattr(self, key)) - set(self.tasks))
            check(not extra, key, f"names tasks not in the study: {extra}")
        # A task's default generations are the paper's: right for a study at the
        # paper's scale, and for a smaller one the silent start of a study of days.
        scaled = _own_scale(self.experiment)
        missing = [t for t in self.tasks if t not in self.generations]
        check(
            not (scaled and missing),
            "generations",
            f"not given for {missing}: a preset that sets its own "
            f"{', '.join(scaled)} must "
            "set each task's generations too (left out, a task takes the paper's)",
        )
        check(
            self.champion_trials == 0 or self.champion_trials >= MIN_CHAMPION_TRIALS,
            "champion_trials",
            f"must be 0 (off) or at least {MIN_CHAMPION_TRIALS}, got "
            f"{self.champion_trials}",
        )
        reserved = sorted(set(self.experiment) & set(STUDY_KEYS))
        check(
            not reserved,
            "experiment",
            f"may not set {reserved}: the study sets them per run "
            "(use the preset's tasks, treatments, generations and task_config)",
        )

    def generations_of(self, task: str) -> int:
        """Generations of every run on ``task``: the preset's, or the task's
        ``default_generations``.

        Raises:
            PresetError: The task names none of the known tasks.
        """
        if task in self.generations:
            return self.generations[task]
        from sdbc_sim.tasks import UnknownTask, resolve_task

        try:
            return resolve_task(task).default_generations
        except UnknownTask as error:
            raise PresetError(f"tasks: {error}") from None

    def treatment(self, name: str | TreatmentSpec) -> TreatmentSpec:
        """One of the preset's treatments, by name."""
        if isinstance(name, TreatmentSpec):
            return name
        for t in self.treatments:
            if t.name == name:
                return t
        raise PresetError(
            f"treatment {name!r} is not in preset {self.name!r} "
            f"({[t.name for t in self.treatments]})"
        )

    def experiment_config(
        self, task: str, treatment: str | TreatmentSpec, seed: int
    ) -> ExperimentConfig:
        """The configuration of one run (validated).

        Raises:
            PresetError: The preset's settings do not make a valid configuration.
        """
        data = {
            **self.experiment,
            "task": task,
            "task_config": dict(self.task_config.get(task, {})),
            "treatment": self.treatment(treatment),
            "generations": self.generations_of(task),
            "seed": seed,
        }
        try:
            return config_from_dict(data).resolved()
        except ConfigError as error:
            raise PresetError(f"preset {self.name!r}, task {task}: {error}") from None

    def validate(self) -> None:
        """Builds every run's configuration and checks every task's settings once,
        so that bad settings fail now, before any run starts."""
        for task in self.tasks:
            for treatment in self.treatments:
                config = self.experiment_config(task, treatment, 0)
            try:
                check_task_config(task, config.task_config)
            except ConfigError as error:
                raise PresetError(f"preset {self.name!r}: {error}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain data (YAML-ready)."""
        return {
            "name": self.name,
            "description": self.description,
            "runs": self.runs,
            "seed": self.seed,
            "tasks": list(self.tasks),
            "treatments": [t.to_plain() for t in self.treatments],
            "generations": {t: self.generations_of(t) for t in self.tasks},
            "task_config": {t: dict(c) for t, c in self.task_config.items()},
            "experiment": to_plain(self.experiment),
            # Left out when off: the study.yaml of earlier studies stays as it was.
            **(
                {"champion_trials": self.champion_trials}
                if self.champion_trials
                else {}
            ),
            **(
                {"predictions": [to_plain(p) for p in self.predictions]}
                if self.predictions
                else {}
            ),
        }

    def same_runs(self, other: StudyPreset) -> bool:
        """Whether ``other`` makes the same runs (its predictions may differ)."""
        return _runs_part(self.to_dict()) == _runs_part(other.to_dict())

    def sizes(self) -> dict[str, Any]:
        """The sizes that decide a study's cost, as a reader wants them."""
        config = self.experiment_config(self.tasks[0], self.treatments[0], 0)
        return {
            "runs per treatment and task": self.runs,
            "treatments": len(self.treatments),
            "population": config.ga.population_size,
            "trials per individual": config.evaluation.trials,
            "re-evaluation trials": config.evaluation.reevaluation_trials,
            "champion re-evaluation trials": self.champion_trials,
            "generations": {t: self.generations_of(t) for t in self.tasks},
        }


_SCALE_KEYS = (
    ("ga", "population_size"),
    ("evaluation", "trials"),
    ("evaluation", "reevaluation_trials"),
)
"""The settings that make a study's scale, besides its generations."""


def _own_scale(experiment: dict[str, Any]) -> list[str]:
    """The scale settings of a preset's ``experiment`` that differ from the
    paper's, as dotted names."""
    defaults = ExperimentConfig()
    own = []
    for section, key in _SCALE_KEYS:
        part = experiment.get(section)
        default = getattr(getattr(defaults, section), key)
        if isinstance(part, dict) and key in part and part[key] != default:
            own.append(f"{section}.{key}")
    return own


def _runs_part(data: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in data.items() if k != "predictions"}


def preset_from_dict(data: Any, where: str = "preset") -> StudyPreset:
    """Builds and validates a preset from plain data (a parsed YAML file).

    Raises:
        PresetError: Naming every bad key, or the first run that cannot be made.
    """
    try:
        preset = load(StudyPreset, data)
    except SettingsError as error:
        raise PresetError(f"{where}: {error}", error.problems) from None
    preset.validate()
    return preset


def load_preset_file(path: str | Path) -> StudyPreset:
    """Reads a preset from a YAML file (its ``name`` defaults to the file's stem)."""
    path = Path(path)
    try:
        data = read_yaml(path, "preset")
    except YamlRefused as error:
        raise PresetError(str(error)) from None
    if isinstance(data, dict):
        data.setdefault("name", path.stem)
    return preset_from_dict(data, str(path))


def preset_directory(start: Path | None = None) -> Path:
    """``configs/study`` of the repository holding this package (found upwards)."""
    here = (start or Path(__file__)).resolve()
    for parent in here.parents:
        candidate = parent / PRESET_DIR
        if candidate.is_dir():
            return candidate
    raise PresetError(
        f"no {PRESET_DIR} directory above {here}: pass the preset as a YAML file path"
    )


def load_preset(name_or_path: str | Path) -> StudyPreset:
    """A named preset (``smoke``, ``local``, ``paper``) or a preset YAML file."""
    text = str(name_or_path)
    if text in PRESET_NAMES or not (text.endswith((".yaml", ".yml"))):
        path = preset_directory() / f"{text}.yaml"
        if not path.is_file():
            raise PresetError(
                f"unknown preset {text!r}; known: {', '.join(PRESET_NAMES)} "
                "(or a path to a YAML file)"
            )
        return load_preset_file(path)
    return load_preset_file(Path(text))


def dump_preset(preset: StudyPreset) -> str:
    """The preset as YAML text that :func:`preset_from_dict` reads back."""
    return yaml.safe_dump(preset.to_dict(), sort_keys=False)
