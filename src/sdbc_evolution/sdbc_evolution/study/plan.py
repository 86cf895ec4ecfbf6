"""The runs of a study: where each one lives, its seed, and how far it got.

A study directory holds one run directory per (task, treatment, run index), in the
layout of :mod:`sdbc_evolution.run.results`::

    STUDY/
      study.yaml                the preset the study was started with
      study_log.jsonl           one line per task of every ``run`` session
      gate_escape/
        fit/run_00/ ...         an ``sdbc-evolve`` output directory
        ns-sd-plus/run_00/ ...
      .discarded/               runs that could not be resumed, moved aside

Run seeds are independent streams of the study seed: seed(task, treatment, r) is
the first 63 bits of ``SeedSequence(study_seed, spawn_key=(crc32(task),
crc32(treatment), r))``. They depend on names, not on positions, so adding a task or
a treatment to a preset leaves every other run unchanged. Two studies whose seeds
differ share no run seed (SeedSequence mixes the study seed into every stream);
the champions' trial seeds come from a branch of their own
(:mod:`sdbc_evolution.study.champions`).

A run of a preset with ``champion_trials`` is finished only when its champions'
re-evaluation is there too (``champion.json``); a run whose generations are done
and whose re-evaluation is missing, killed halfway or made with other seeds is
:attr:`RunProgress.REEVALUATE`: the runner re-evaluates it, nothing else.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np

from sdbc_evolution.ga.treatments import TreatmentSpec, treatment_directory
from sdbc_evolution.run.checkpoint import CheckpointError, load_checkpoint
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    load_config,
)
from sdbc_evolution.run.evaluators import TaskInfo
from sdbc_evolution.run.experiment import task_spec
from sdbc_evolution.run.lock import RunBusy, RunLock
from sdbc_evolution.run.results import CONFIG_FILE, ResultsDirectory, RunDamaged
from sdbc_evolution.study.champions import (
    ChampionError,
    champion_seeds,
    check_champions,
)
from sdbc_evolution.study.presets import StudyPreset

STUDY_FILE = "study.yaml"
"""The preset a study directory was started with."""
LOG_FILE = "study_log.jsonl"
"""Timings of the ``run`` sessions, one JSON object per task and session."""
DISCARDED_DIR = ".discarded"
"""Where runs that could not be resumed are moved."""


def _name(treatment: str | TreatmentSpec) -> str:
    return treatment.name if isinstance(treatment, TreatmentSpec) else treatment


def run_seed(
    study_seed: int, task: str, treatment: str | TreatmentSpec, index: int
) -> int:
    """The seed of run ``index`` of ``treatment`` on ``task`` (see module docstring)."""
    sequence = np.random.SeedSequence(
        study_seed,
        spawn_key=(
            zlib.crc32(task.encode()),
            zlib.crc32(_name(treatment).encode()),
            index,
        ),
    )
    return int(sequence.generate_state(1, np.uint64)[0] >> np.uint64(1))


@dataclass(frozen=True)
class RunSpec:
    """One run of a study.

    Attributes:
        task: Task name.
        treatment: Treatment.
        index: Run index within (task, treatment), from 0.
        path: The run directory.
        config: The run's resolved configuration.
        champion_seeds: Trial seeds of its champions' re-evaluation (empty: the
            preset re-evaluates none).
    """

    task: str
    treatment: TreatmentSpec
    index: int
    path: Path
    config: ExperimentConfig
    champion_seeds: tuple[int, ...] = ()

    @property
    def name(self) -> str:
        """``task/treatment/run_NN``: how reports and progress name the run."""
        return f"{self.task}/{self.treatment.directory}/run_{self.index:02d}"

    @property
    def generations(self) -> int:
        """Generations of the run, as its configuration resolves them."""
        return self.config.resolved_generations


def run_directory(
    root: Path, task: str, treatment: str | TreatmentSpec, index: int
) -> Path:
    """The directory of run ``index`` of a task and treatment under a study's
    ``root``."""
    directory = treatment_directory(_name(treatment))
    return Path(root) / task / directory / f"run_{index:02d}"


def study_plan(
    preset: StudyPreset, root: str | Path, tasks: tuple[str, ...] | None = None
) -> list[RunSpec]:
    """Every run of the study on ``tasks`` (default: all of the preset's).

    Runs come task by task; within a task, run index by run index, every treatment
    in turn, so that a study stopped early has about as many runs of each.
    """
    chosen = preset.tasks if tasks is None else tasks
    unknown = [t for t in chosen if t not in preset.tasks]
    if unknown:
        raise ValueError(
            f"task(s) {unknown} not in preset {preset.name!r} "
            f"(its tasks: {', '.join(preset.tasks)})"
        )
    root = Path(root)
    return [
        RunSpec(
            task=task,
            treatment=treatment,
            index=index,
            path=run_directory(root, task, treatment, index),
            config=preset.experiment_config(
                task, treatment, run_seed(preset.seed, task, treatment, index)
            ),
            champion_seeds=tuple(
                int(s)
                for s in champion_seeds(
                    preset.seed, task, treatment.name, index, preset.champion_trials
                )
            )
            if preset.champion_trials
            else (),
        )
        for task in chosen
        for index in range(preset.runs)
        for treatment in preset.treatments
    ]


@dataclass(frozen=True)
class Shard:
    """Share ``index`` of ``count`` of a study's runs, for array jobs on a cluster.

    Shard k of n takes the plan's runs k, k + n, k + 2n, ...: the shards partition
    the study, each run in exactly one, and as the plan interleaves treatments,
    every shard gets about as many of each. Runs are independent and their seeds
    depend on names only, so a study run in n shards (at once, on a shared
    filesystem) equals the study run in one go.

    Attributes:
        index: Which share, from 0.
        count: How many shares.
    """

    index: int
    count: int

    def __post_init__(self) -> None:
        if self.count < 1 or not 0 <= self.index < self.count:
            raise ValueError(
                f"shard {self.index}/{self.count}: needs 0 <= index < count"
            )

    @classmethod
    def parse(cls, text: str) -> Shard:
        """``"K/N"``, as a command line gives it."""
        index, slash, count = text.partition("/")
        if not (slash and index.isdigit() and count.isdigit()):
            raise ValueError(f"shard {text!r}: expected K/N, whole numbers, 0 <= K < N")
        return cls(int(index), int(count))

    def select(self, plan: list[RunSpec]) -> list[RunSpec]:
        """This shard's runs of ``plan``."""
        return plan[self.index :: self.count]

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"


class RunProgress(str, Enum):
    """How far a run directory got."""

    NEW = "new"
    """Nothing there yet: the run starts."""
    PARTIAL = "partial"
    """A valid checkpoint before the last generation: the run resumes."""
    REEVALUATE = "reevaluate"
    """Every generation done, the champions' re-evaluation the preset asks for
    missing or unusable: it is done (again)."""
    FINISHED = "finished"
    """Checkpoint at the last generation (and the champions re-evaluated, if the
    preset asks for it): the run is skipped."""
    BROKEN = "broken"
    """Results without a usable checkpoint, or damaged outputs the checkpoint
    vouches for: moved aside, the run starts again."""
    BUSY = "busy"
    """Another process holds the run's lock (another session writes it): left
    to it."""


@dataclass(frozen=True)
class RunStatus:
    """A run's state, the generations it has, and why it is broken if it is."""

    state: RunProgress
    generations_done: int = 0
    detail: str = ""


_NAMES: dict[tuple[str, str], tuple[str, ...]] = {}


def _sdbc_names(config: ExperimentConfig) -> tuple[str, ...]:
    spec = task_spec(config)
    if spec.key() not in _NAMES:
        _NAMES[spec.key()] = TaskInfo.of(spec).sdbc_names
    return _NAMES[spec.key()]


def run_status(spec: RunSpec) -> RunStatus:
    """Reads (never changes) the run directory of ``spec``: its checkpoint, and
    every output the checkpoint vouches for (see ``ResultsDirectory.verify``).

    It does not look at the run's lock: a caller that acts on the answer holds
    the lock while it reads and acts (see :func:`locked_status`).
    """
    results = ResultsDirectory(spec.path, _sdbc_names(spec.config))
    if not spec.path.exists() or not results.holds_a_run():
        return RunStatus(RunProgress.NEW)
    try:
        existing = load_config(spec.path / CONFIG_FILE)
    except ConfigError as error:
        return RunStatus(RunProgress.BROKEN, detail=str(error))
    if existing.replace(generations=None) != spec.config.replace(generations=None):
        return RunStatus(
            RunProgress.BROKEN,
            detail=f"{CONFIG_FILE} differs from the preset's configuration of this run",
        )
    try:
        checkpoint = load_checkpoint(results.checkpoint_path, spec.config.to_dict())
    except CheckpointError as error:
        return RunStatus(RunProgress.BROKEN, detail=str(error))
    try:
        results.verify(checkpoint.generation, spec.config.ga.population_size)
    except RunDamaged as error:
        return RunStatus(RunProgress.BROKEN, detail=str(error))
    if checkpoint.generation >= spec.generations:
        if spec.champion_seeds:
            try:
                check_champions(
                    spec.path, np.array(spec.champion_seeds), spec.generations
                )
            except (ChampionError, OSError, ValueError, IndexError) as error:
                return RunStatus(
                    RunProgress.REEVALUATE, checkpoint.generation, str(error)
                )
        return RunStatus(RunProgress.FINISHED, checkpoint.generation)
    return RunStatus(RunProgress.PARTIAL, checkpoint.generation)


def locked_status(spec: RunSpec) -> tuple[RunLock, RunStatus]:
    """The run's status read under its lock, and the lock, held unless the state
    is BUSY or NEW with no directory yet (the caller releases it)."""
    lock = RunLock(spec.path)
    if spec.path.is_dir():
        try:
            lock.acquire()
        except RunBusy as busy:
            return lock, RunStatus(RunProgress.BUSY, detail=str(busy))
    try:
        return lock, run_status(spec)
    except BaseException:
        lock.release()
        raise


def discard(spec: RunSpec, root: str | Path) -> Path:
    """Moves a broken run directory under ``STUDY/.discarded`` and returns where."""
    target_dir = Path(root) / DISCARDED_DIR
    target_dir.mkdir(parents=True, exist_ok=True)
    base = spec.name.replace("/", "-")
    n = 1
    while (target := target_dir / f"{base}-{n}").exists():
        n += 1
    spec.path.rename(target)
    return target
