"""What a run's configuration is made of, resolved one way for every front end.

``sdbc-evolve`` (:mod:`sdbc_evolution.run.cli`) and the evolution node
(:mod:`sdbc_evolution.nodes.evolution_node`) both ask for a run the same way: a
configuration file or the quick-start one (or, when resuming, the run's own), with
some settings overridden. Each fills a :class:`ConfigRequest` from its own inputs
(flags, ROS parameters) and :func:`resolve_config` turns it into the run's
:class:`~sdbc_evolution.run.config.ExperimentConfig`; :func:`check_before_run`
then makes the checks both make before a run directory exists.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sdbc_sim.settings import SettingsError

from sdbc_evolution.run.checkpoint import CheckpointError
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    check_task_config,
    load_config,
    load_treatment,
    quickstart_config,
)
from sdbc_evolution.run.evaluators import TaskInfo, probe_task
from sdbc_evolution.run.experiment import task_spec
from sdbc_evolution.run.footprint import check_footprint
from sdbc_evolution.run.results import CONFIG_FILE

RESULTS_ROOT = Path("results")
"""Where runs go when no output directory is given."""


@dataclass(frozen=True)
class ConfigRequest:
    """A run's configuration as asked for; None everywhere means "the base's".

    Attributes:
        config: A YAML experiment configuration; None: the run's own when
            resuming, the quick-start one otherwise.
        resume: Continue the run in ``out`` (its configuration is the base).
        out: The run's output directory.
        task: Task name.
        treatment: A paper treatment's name (``ns-sd+``, ...) or a YAML file
            declaring a treatment.
        generations: Generations to run.
        population: Population size.
        trials: Trials per individual.
        physics: The engine's physics model (``evaluation.physics``).
        seed: Seed of the run.
        task_config: The task's settings, replacing the base's.
    """

    config: Path | None = None
    resume: bool = False
    out: Path | None = None
    task: str | None = None
    treatment: str | None = None
    generations: int | None = None
    population: int | None = None
    trials: int | None = None
    physics: str | None = None
    seed: int | None = None
    task_config: Mapping[str, Any] | None = None


def resolve_config(request: ConfigRequest) -> ExperimentConfig:
    """The run's configuration: a file (given, or the run's own when resuming), or
    the quick-start one, with the request's overrides on top and every default
    filled in.

    Raises:
        ConfigError: A bad file or override, or ``resume`` without ``out``.
        CheckpointError: ``resume`` where ``out`` holds no run.
    """
    out = request.out
    if request.resume and out is None:
        raise ConfigError("--resume needs --out DIR, the run to continue")
    if request.config is not None:
        config = load_config(request.config)
    elif request.resume and out is not None:
        if not (out / CONFIG_FILE).is_file():
            raise CheckpointError(f"--resume: {out} holds no run ({CONFIG_FILE})")
        config = load_config(out / CONFIG_FILE)
        _check_named_code(config.task, request.task, out / CONFIG_FILE)
    else:
        config = quickstart_config()
    changes: dict[str, Any] = {}
    if request.treatment is not None:
        changes["treatment"] = load_treatment(request.treatment)
    for name in ("task", "generations", "seed"):
        value = getattr(request, name)
        if value is not None:
            changes[name] = value
    if request.task_config is not None:
        changes["task_config"] = dict(request.task_config)
    for section, key, value in (
        ("ga", "population_size", request.population),
        ("evaluation", "trials", request.trials),
        ("evaluation", "physics", request.physics),
    ):
        if value is None:
            continue
        try:
            # From the section as changed so far: --trials and --physics both
            # change evaluation, and each must keep the other's change.
            changes[section] = dataclasses.replace(
                changes.get(section, getattr(config, section)), **{key: value}
            )
        except SettingsError as error:
            problem = error.prefixed(section)
            raise ConfigError(str(problem), problem.problems) from None
    try:
        return config.replace(**changes).resolved()
    except (TypeError, ValueError) as error:
        raise ConfigError(str(error)) from None


def check_before_run(config: ExperimentConfig, workers: int = 1) -> TaskInfo:
    """What every front end checks of a resolved configuration of this project's
    engine before a run directory exists: the task's own settings, the memory
    the run needs with ``workers`` local worker processes
    (:func:`~sdbc_evolution.run.footprint.check_footprint`), and one trial in
    this process (:func:`~sdbc_evolution.run.evaluators.probe_task`: values in
    the contract's ranges, task states that fit the description).

    Returns:
        The task's sizes and dimension names.

    Raises:
        ConfigError: A bad task setting.
        ValueError: Too little memory, or a task that fails its first trial;
            the message says which.
    """
    check_task_config(config.task, config.task_config)
    spec = task_spec(config)
    info = TaskInfo.of(spec)
    check_footprint(config, info, workers=workers)
    probe_task(spec, info)
    return info


def _check_named_code(task: str, given: str | None, where: Path) -> None:
    """Refuses to resume a run whose task is a Python file unless the user names
    the same file: a run directory is data, and whoever could write its
    ``config.yaml`` would otherwise choose the code that ``--resume`` runs."""
    from sdbc_sim.tasks import is_file_reference, task_reference

    if not is_file_reference(task):
        return
    if given is not None and task_reference(given) == task:
        return
    raise ConfigError(
        f"--resume: {where} names the task file {task}; code named by a run "
        f"directory is run only if you name it too: add --task {task}"
    )


def default_out(config: ExperimentConfig) -> Path:
    """``results/<task>-<treatment>-seed<seed>``, numbered if already taken."""
    base = (
        RESULTS_ROOT
        / f"{task_label(config.task)}-{config.treatment.name}-seed{config.seed}"
    )
    if not base.exists():
        return base
    n = 2
    while (candidate := base.with_name(f"{base.name}-{n}")).exists():
        n += 1
    return candidate


def task_label(reference: str) -> str:
    """A name for ``reference`` fit for a folder: the task's registered ``name``
    for a ``module:Class`` or ``file.py:Class`` reference, else the reference with
    anything but letters, digits, ``-``, ``_`` and ``.`` replaced."""
    from sdbc_sim.tasks import find_task

    task_class = find_task(reference) if ":" in reference else None
    label = task_class.name if task_class is not None else reference
    return re.sub(r"[^A-Za-z0-9_.-]", "_", label)
