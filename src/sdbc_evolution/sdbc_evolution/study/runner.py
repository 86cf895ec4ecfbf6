"""The study runner: every run of a study, resumable, with one progress display.

Runs go task by task (so a task's wall time is measured on its own). Finished runs
are skipped, interrupted runs resume from their checkpoint (the experiment runner's
bit-identical ``--resume``), and a run directory that holds results but no usable
checkpoint, or whose checkpoint vouches for an output that is missing or damaged,
is moved under ``STUDY/.discarded`` and started again; each of these is said by
name.

A run's status is read under its lock (``sdbc_evolution.run.lock``), and the run is
written under it. A run another session holds (two sessions on one study, or a
run someone resumes by hand) is busy: left to its writer, named, and the session
ends with :attr:`StudyOutcome.busy` set. Shards lock only their own runs.

Where the work goes:

- **local** (default): up to ``workers`` processes at once (default: every core),
  made by :mod:`sdbc_evolution.run.processes`, each evaluating in process. A study
  is many independent runs, so this keeps every core busy through the serial parts
  of a generation (ranking, mutual information, output) that a pool shared by one
  run would leave idle. ``workers=1`` runs everything in this process.
  Each process runs a group of ``joined_runs`` runs of one task
  (:mod:`sdbc_evolution.run.joined`): their generations share one engine batch,
  which at the local studies' sizes costs a robot-step less than the small batch
  of one run would. By default a group holds as many runs as make about
  :data:`JOINED_TRIALS` trials per batch, fewer where that leaves a core idle;
  runs whose characterisations do not all average their trials run alone.
- **Dask** (``scheduler``): one run after the other, each generation's trials spread
  over the cluster by :class:`~sdbc_evolution.run.evaluators.DaskEvaluator`.

A preset with ``champion_trials`` makes a run end with its champions' re-evaluation
(:mod:`.champions`), done in the run's process under its lock; a run found with its
generations done and that re-evaluation missing is re-evaluated and nothing else.

Each run directory gets ``study_run.json``: how each stretch of its generations was
run (evaluator, workers per run, runs side by side), which the cost analysis needs
to turn seconds into per-worker rates.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from sdbc_sim.limits import MAX_WORKERS

from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.run.evaluators import (
    DEFAULT_CONNECT_TIMEOUT,
    Evaluator,
    LocalEvaluator,
    SchedulerLost,
    TaskInfo,
    TaskSpec,
    make_evaluator,
)
from sdbc_evolution.run.experiment import (
    Experiment,
    ExperimentError,
    describe_failure,
    task_spec,
)
from sdbc_evolution.run.footprint import check_footprint
from sdbc_evolution.run.joined import JOINED_TRIALS, run_joined
from sdbc_evolution.run.lock import RunBusy
from sdbc_evolution.run.processes import limit_threads, message_queue, start_process
from sdbc_evolution.run.results import atomic_write_bytes
from sdbc_evolution.run.stopping import STOP_SIGNALS, interrupt, stop_signals_to
from sdbc_evolution.study.champions import reevaluate_champions
from sdbc_evolution.study.plan import (
    LOG_FILE,
    STUDY_FILE,
    RunProgress,
    RunSpec,
    RunStatus,
    Shard,
    discard,
    locked_status,
    run_status,
    study_plan,
)
from sdbc_evolution.study.presets import StudyPreset, dump_preset, load_preset_file

EXECUTION_FILE = "study_run.json"
"""Per run directory: how its generations were run (see module docstring)."""
POLL_SECONDS = 0.5
"""How often the parent looks at its child processes between messages."""


class StudyError(RuntimeError):
    """A study that cannot start; the message says why."""


@dataclass(frozen=True)
class Execution:
    """Where runs go.

    Attributes:
        workers: Local processes side by side (None: every core); ignored with
            Dask.
        scheduler: Address of a Dask scheduler, or None for local.
        connect_timeout: Seconds to wait for the scheduler.
        joined_runs: Most runs of a task joined in one process (module
            docstring); None: enough for about :data:`JOINED_TRIALS` trials per
            batch; 1: every run alone. Local only.
    """

    workers: int | None = None
    scheduler: str | None = None
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT
    joined_runs: int | None = None

    def __post_init__(self) -> None:
        if self.workers is not None and self.workers < 1:
            raise ValueError(f"workers must be at least 1, got {self.workers}")
        if self.joined_runs is not None and not 1 <= self.joined_runs <= MAX_WORKERS:
            raise ValueError(
                f"joined runs must be from 1 to {MAX_WORKERS}, got {self.joined_runs}"
            )
        if self.workers is not None and self.scheduler is not None:
            raise ValueError(
                "workers and scheduler exclude each other: the Dask cluster "
                "decides its own workers"
            )

    @property
    def concurrent_runs(self) -> int:
        """Runs at once: one on a Dask cluster (its workers share each run), else the
        workers or the CPU count."""
        if self.scheduler is not None:
            return 1
        return self.workers if self.workers is not None else (os.cpu_count() or 1)

    def joined(self, config: ExperimentConfig) -> int:
        """Most runs of ``config``'s task joined in one process (1 with Dask)."""
        if self.scheduler is not None:
            return 1
        if self.joined_runs is not None:
            return self.joined_runs
        evaluation = config.evaluation
        per_generation = (
            config.ga.population_size * evaluation.trials
            + evaluation.reevaluation_trials
        )
        return max(1, min(MAX_WORKERS, JOINED_TRIALS // per_generation))


@dataclass
class RunOutcome:
    """What became of one run in a session."""

    name: str
    generations_done: int
    finished: bool
    error: str = ""
    interrupted: bool = False
    busy: str = ""
    system: bool = False
    """The system refused (a full disk, no memory): every run would fail alike."""
    by_other: bool = False
    """Found finished by another session: counted as skipped, not as this one's."""


@dataclass
class StudyOutcome:
    """What a ``run`` session did.

    Attributes:
        skipped: Runs already finished before the session.
        ran: Runs this session worked on.
        discarded: (run name, where it went, why) of runs moved aside.
        failed: Runs that stopped on an error.
        busy: Runs another process was writing, left to it.
        interrupted: True if the session was stopped (Ctrl-C).
        task_seconds: Wall time per task in this session.
    """

    skipped: list[str] = field(default_factory=list)
    ran: list[RunOutcome] = field(default_factory=list)
    discarded: list[tuple[str, Path, str]] = field(default_factory=list)
    failed: list[RunOutcome] = field(default_factory=list)
    busy: list[str] = field(default_factory=list)
    interrupted: bool = False
    task_seconds: dict[str, float] = field(default_factory=dict)


Say = Callable[[str], None]


def prepare_study_directory(preset: StudyPreset, root: Path) -> None:
    """Creates ``root`` with ``study.yaml``, or checks that it holds this preset
    (the same runs; its predictions are updated to the preset's)."""
    root.mkdir(parents=True, exist_ok=True)
    path = root / STUDY_FILE
    if path.exists():
        try:
            existing = load_preset_file(path)
        except ValueError as error:
            raise StudyError(f"{path} cannot be read: {error}") from None
        if not existing.same_runs(preset):
            raise StudyError(
                f"{root} holds a study of another preset ({existing.name!r}, or the "
                f"same name with other settings): choose another output directory"
            )
        if existing.predictions == preset.predictions:
            return
        # Predictions judge the runs and make none of them: the analysis reads
        # the preset's current ones.
    atomic_write_bytes(path, dump_preset(preset).encode())


def run_study(
    preset: StudyPreset,
    root: str | Path,
    tasks: Sequence[str] | None = None,
    execution: Execution | None = None,
    quiet: bool = False,
    say: Say | None = None,
    command: Sequence[str] | None = None,
    shard: Shard | None = None,
) -> StudyOutcome:
    """Runs (or resumes) the study ``preset`` in ``root``.

    Args:
        preset: The study.
        root: The study directory.
        tasks: Tasks to run now (default: all of the preset's).
        execution: Local or Dask, and how many workers.
        quiet: No progress bar.
        say: Where messages go (default: stderr).
        command: The command line, for the study log.
        shard: Only this share of the runs (see :class:`Shard`); sessions of
            different shards may run at once on the same directory.

    Raises:
        StudyError: The directory holds another study.
        ValueError: A task not in the preset.
    """
    execution = execution or Execution()
    say = say or (lambda text: print(text, file=sys.stderr))
    root = Path(root)
    plan = study_plan(preset, root, tuple(tasks) if tasks is not None else None)
    if shard is not None:
        runs = len(plan)
        plan = shard.select(plan)
        if not plan:
            raise StudyError(
                f"shard {shard} holds no runs: the study has {runs}, so at most "
                f"{runs} shards"
            )
    for spec in {spec.task: spec for spec in plan}.values():
        # Runs of a task differ in seed and treatment only: one check per task,
        # for as many of its runs side by side as will run at once.
        runs = sum(s.task == spec.task for s in plan)
        slots = execution.concurrent_runs
        check_footprint(
            spec.config,
            TaskInfo.of(task_spec(spec.config)),
            runs=min(runs, slots * execution.joined(spec.config)),
            processes=min(runs, slots) if slots > 1 else 0,
        )
    if execution.scheduler is not None:
        # An unreachable scheduler fails here, before anything is written.
        make_evaluator(
            task_spec(plan[0].config),
            scheduler=execution.scheduler,
            timeout=execution.connect_timeout,
        ).close()
    prepare_study_directory(preset, root)
    outcome = StudyOutcome()
    todo: list[tuple[RunSpec, int]] = []
    for spec in plan:
        lock, status = locked_status(spec)
        try:
            if status.state is RunProgress.BUSY:
                outcome.busy.append(spec.name)
                say(f"{spec.name}: left alone: {status.detail}")
                continue
            if status.state is RunProgress.FINISHED:
                outcome.skipped.append(spec.name)
                continue
            if status.state is RunProgress.BROKEN:
                where = discard(spec, root)
                outcome.discarded.append((spec.name, where, status.detail))
                say(f"{spec.name}: cannot resume ({status.detail}); moved to {where}")
                status = RunStatus(RunProgress.NEW)
            if status.state is RunProgress.REEVALUATE:
                say(f"{spec.name}: champions to re-evaluate ({status.detail})")
        finally:
            # Released for the process that runs it, which locks it again and
            # reads the status anew (another session may finish it meanwhile).
            lock.release()
        todo.append((spec, status.generations_done))
    if outcome.skipped:
        say(f"{len(outcome.skipped)} of {len(plan)} runs already finished: skipped")
    progress = _Progress(plan, todo, preset.name, quiet)
    try:
        for task in dict.fromkeys(spec.task for spec in plan):
            task_todo = [(s, done) for s, done in todo if s.task == task]
            if not task_todo:
                continue
            started = time.time()
            results: list[RunOutcome] = []
            aborted = ""
            groups = _groups(task_todo, execution)
            try:
                if execution.scheduler is not None:
                    results = _run_dask(task_todo, execution, progress)
                elif execution.concurrent_runs == 1:
                    results = _run_in_process(groups, progress)
                else:
                    results = _run_processes(groups, execution, progress)
            except BaseException as error:
                aborted = type(error).__name__
                raise
            finally:
                elapsed = time.time() - started
                outcome.task_seconds[task] = elapsed
                _log_session(
                    root,
                    {
                        "task": task,
                        "preset": preset.name,
                        "command": list(command) if command is not None else None,
                        "started": datetime.fromtimestamp(started, UTC).isoformat(
                            timespec="seconds"
                        ),
                        "elapsed_s": round(elapsed, 3),
                        "evaluator": "dask" if execution.scheduler else "local",
                        "concurrent_runs": execution.concurrent_runs,
                        "joined_runs": max(len(g) for g in groups),
                        "cpu_count": os.cpu_count(),
                        "runs": sum(s.task == task for s in plan),
                        "finished_before": sum(
                            n.startswith(f"{task}/") for n in outcome.skipped
                        ),
                        "worked_on": len(results),
                        "finished_now": sum(
                            r.finished and not r.by_other for r in results
                        ),
                        "failed": [r.name for r in results if r.error],
                        "interrupted": aborted == "KeyboardInterrupt"
                        or any(r.interrupted for r in results),
                        "aborted_by": aborted or None,
                        "shard": str(shard) if shard is not None else None,
                    },
                )
            for result in results:
                if result.busy:
                    outcome.busy.append(result.name)
                    say(f"{result.name}: left alone: {result.busy}")
                    continue
                if result.by_other:
                    outcome.skipped.append(result.name)
                    continue
                if result.system:
                    # As in process: one line and exit 2, the study resumable.
                    raise StudyError(f"{result.name}: {result.error}")
                outcome.ran.append(result)
                if result.error:
                    outcome.failed.append(result)
                    say(f"{result.name}: failed:\n{result.error}")
            if any(r.interrupted for r in results):
                outcome.interrupted = True
                break
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        progress.close()
    return outcome


class _Progress:
    """One bar over every generation of the session, with the runs done and the
    runs in progress (and their generation) after it; tqdm's estimate of the time
    left assumes the generations to come cost what the last ones did."""

    def __init__(
        self,
        plan: list[RunSpec],
        todo: list[tuple[RunSpec, int]],
        name: str,
        quiet: bool,
    ) -> None:
        from tqdm import tqdm

        self.runs_total = len(plan)
        self.runs_done = self.runs_total - len(todo)
        total = sum(spec.generations for spec in plan)
        pending = {spec.name for spec, _ in todo}
        done = sum(s.generations for s in plan if s.name not in pending) + sum(
            d for _, d in todo
        )
        self.active: dict[str, str] = {}
        self.bar = tqdm(
            total=total,
            initial=done,
            desc=f"study {name}",
            unit="gen",
            disable=quiet,
            dynamic_ncols=True,
        )
        self._refresh()

    def generation(self, spec_name: str, done: int, total: int) -> None:
        self.active[spec_name] = f"{done}/{total}"
        self._refresh(now=False)
        self.bar.update(1)

    def started(self, spec_name: str, done: int, total: int) -> None:
        self.active[spec_name] = f"{done}/{total}"
        self._refresh()

    def ended(self, spec_name: str, finished: bool) -> None:
        self.active.pop(spec_name, None)
        if finished:
            self.runs_done += 1
        self._refresh()

    def _refresh(self, now: bool = True) -> None:
        running = ", ".join(f"{n} {g}" for n, g in self.active.items())
        self.bar.set_postfix_str(
            f"runs {self.runs_done}/{self.runs_total}"
            + (f" | {running}" if running else ""),
            refresh=now,
        )

    def close(self) -> None:
        self.bar.close()


def execute_run(
    spec: RunSpec,
    evaluator: Evaluator,
    on_generation: Callable[[int], None],
    execution_note: dict[str, Any],
) -> RunOutcome:
    """Creates or resumes one run and takes it to its last generation, under the
    run's lock, which it takes before reading the run's status.

    A run another process holds is reported ``busy`` and left alone; one found
    finished (by another session since the study looked) is reported finished
    and left as it is. A Ctrl-C stops it between or inside a generation (the
    checkpoint is atomic, so the run resumes where it stopped) and is reported as
    ``interrupted``.
    """
    lock, status = locked_status(spec)
    if status.state is RunProgress.NEW and not lock.held:
        # No directory yet: make it locked, then look again under the lock.
        try:
            lock.acquire()
        except RunBusy as busy:
            return RunOutcome(spec.name, 0, finished=False, busy=str(busy))
        status = run_status(spec)
    if status.state is RunProgress.BUSY:
        return RunOutcome(spec.name, 0, finished=False, busy=status.detail)
    try:
        if status.state is RunProgress.FINISHED:
            # Finished by another session since this one looked: its run, not ours.
            lock.release()
            return RunOutcome(
                spec.name, status.generations_done, finished=True, by_other=True
            )
        if status.state is RunProgress.REEVALUATE:
            outcome = RunOutcome(spec.name, status.generations_done, finished=False)
            try:
                _reevaluate_champions(spec, evaluator)
                outcome.finished = True
            except KeyboardInterrupt:
                outcome.interrupted = True
            finally:
                lock.release()
            return outcome
        if status.state is RunProgress.PARTIAL:
            experiment = Experiment.resume(spec.config, spec.path, evaluator, lock=lock)
        elif status.state is RunProgress.NEW:
            experiment = Experiment.create(spec.config, spec.path, evaluator, lock=lock)
        else:
            raise ExperimentError(f"{spec.path} was damaged meanwhile: {status.detail}")
    except BaseException:
        lock.release()
        raise
    first = experiment.state.generation
    started = time.time()
    outcome = RunOutcome(spec.name, first, finished=False)
    with experiment:
        try:
            experiment.run(lambda record: on_generation(record.generation + 1))
            # Still under the run's lock: the run is finished once its champions
            # are judged on fresh trials (a Ctrl-C here redoes only this).
            _reevaluate_champions(spec, evaluator)
            outcome.finished = True
        except KeyboardInterrupt:
            outcome.interrupted = True
        finally:
            outcome.generations_done = experiment.state.generation
            _note_execution(spec.path, first, outcome, started, execution_note)
    return outcome


def _reevaluate_champions(spec: RunSpec, evaluator: Evaluator) -> None:
    if spec.champion_seeds:
        reevaluate_champions(
            spec.path, spec.config, evaluator, np.array(spec.champion_seeds)
        )


def _note_execution(
    path: Path,
    first: int,
    outcome: RunOutcome,
    started: float,
    note: dict[str, Any],
) -> None:
    file = path / EXECUTION_FILE
    try:
        segments = json.loads(file.read_text()) if file.exists() else []
    except (OSError, ValueError):
        segments = []
    if outcome.generations_done > first:
        segments.append(
            {
                "from_generation": first,
                "to_generation": outcome.generations_done,
                "elapsed_s": time.time() - started,
                **note,
            }
        )
    atomic_write_bytes(file, json.dumps(segments, indent=1).encode())


def _note(execution: Execution, workers: int) -> dict[str, Any]:
    return {
        "evaluator": "dask" if execution.scheduler is not None else "local",
        "workers_per_run": workers,
        "concurrent_runs": execution.concurrent_runs,
        "cpu_count": os.cpu_count(),
    }


def _run_one_by_one(
    todo: list[tuple[RunSpec, int]],
    progress: _Progress,
    evaluator_for: Callable[[RunSpec], AbstractContextManager[Evaluator]],
    note: dict[str, Any],
) -> list[RunOutcome]:
    """Runs ``todo`` in turn, each on ``evaluator_for(spec)``; a failed run is
    recorded and the next one starts, an interrupted one stops the rest."""
    results = []
    for spec, done in todo:
        progress.started(spec.name, done, spec.generations)

        def advance(generation: int, spec: RunSpec = spec) -> None:
            progress.generation(spec.name, generation, spec.generations)

        with evaluator_for(spec) as evaluator:
            try:
                result = execute_run(spec, evaluator, advance, note)
            except (SchedulerLost, OSError, MemoryError):
                raise  # every run after this one would fail the same way
            except Exception as error:
                failure = describe_failure(error, "sdbc-study")
                result = RunOutcome(spec.name, done, False, failure)
        progress.ended(spec.name, result.finished)
        results.append(result)
        if result.interrupted:
            break
    return results


Group = list[tuple[RunSpec, int]]
"""Runs (with their generations done) that share one process."""


def _groups(todo: Group, execution: Execution) -> list[Group]:
    """The runs of ``todo`` (one task) in the groups that share a process: runs
    of one task spec that joins requests, at most ``execution.joined`` of them,
    cut so that no process slot is left with fewer groups than the others."""
    kinds: list[tuple[TaskSpec, Group]] = []
    for item in todo:
        spec = task_spec(item[0].config)
        same = next((runs for kind, runs in kinds if kind.evaluates_like(spec)), None)
        if same is None:
            kinds.append((spec, [item]))
        else:
            same.append(item)
    groups: list[Group] = []
    slots = execution.concurrent_runs
    for spec, runs in kinds:
        most = execution.joined(runs[0][0].config)
        if most == 1 or not LocalEvaluator(spec, workers=1).joins_requests:
            groups += [[item] for item in runs]
            continue
        rounds = math.ceil(len(runs) / (slots * most))
        size = math.ceil(len(runs) / (slots * rounds))
        groups += [runs[i : i + size] for i in range(0, len(runs), size)]
    return groups


def _run_in_process(groups: list[Group], progress: _Progress) -> list[RunOutcome]:
    note = _note(Execution(workers=1), 1)
    lock = threading.Lock()

    def advance(spec: RunSpec, generation: int) -> None:
        with lock:  # the joined runs' threads share the display
            progress.generation(spec.name, generation, spec.generations)

    results: list[RunOutcome] = []
    for group in groups:
        if len(group) == 1:
            results += _run_one_by_one(
                group,
                progress,
                lambda spec: LocalEvaluator(task_spec(spec.config), workers=1),
                note,
            )
        else:
            for spec, done in group:
                progress.started(spec.name, done, spec.generations)
            joined = _run_group([spec for spec, _ in group], note, advance)
            for result in joined:
                progress.ended(result.name, result.finished)
            results += joined
        if any(r.interrupted for r in results):
            break
    return results


def _run_group(
    group: list[RunSpec],
    note: dict[str, Any],
    advance: Callable[[RunSpec, int], None],
) -> list[RunOutcome]:
    """Runs ``group`` joined (:mod:`sdbc_evolution.run.joined`) in this process;
    each run's failure is its own outcome, as a run alone in a process."""
    note = {**note, "joined_runs": len(group)}

    def job(spec: RunSpec) -> tuple[TaskSpec, Callable[[Evaluator], RunOutcome]]:
        def work(evaluator: Evaluator) -> RunOutcome:
            return _outcome(
                spec,
                lambda: execute_run(spec, evaluator, lambda g: advance(spec, g), note),
            )

        return task_spec(spec.config), work

    with LocalEvaluator(task_spec(group[0].config), workers=1) as evaluator:
        outcomes = run_joined(evaluator, [job(spec) for spec in group])
    return [
        outcome if outcome is not None else _interrupted(spec)
        for spec, outcome in zip(group, outcomes, strict=True)
    ]


def _outcome(spec: RunSpec, run: Callable[[], RunOutcome]) -> RunOutcome:
    """``run()``, or what stopped it as the run's outcome: interrupted, or failed
    (``system`` for an error every run would meet: no disk, no memory)."""
    try:
        return run()
    except KeyboardInterrupt:
        return _interrupted(spec)
    except Exception as error:
        return RunOutcome(
            spec.name,
            run_status(spec).generations_done,
            False,
            describe_failure(error, "sdbc-study"),
            system=isinstance(error, (OSError, MemoryError)),
        )


def _interrupted(spec: RunSpec) -> RunOutcome:
    """The outcome of ``spec`` stopped by Ctrl-C, at the generations it has."""
    return RunOutcome(
        spec.name, run_status(spec).generations_done, False, interrupted=True
    )


def _run_dask(
    todo: list[tuple[RunSpec, int]], execution: Execution, progress: _Progress
) -> list[RunOutcome]:
    # One cluster connection serves every run, each evaluated with its own task
    # spec: treatments differ in the characterisations the workers compute.
    with make_evaluator(
        task_spec(todo[0][0].config),
        scheduler=execution.scheduler,
        timeout=execution.connect_timeout,
    ) as evaluator:

        def evaluator_for(spec: RunSpec) -> AbstractContextManager[Evaluator]:
            evaluator.spec = task_spec(spec.config)
            return contextlib.nullcontext(evaluator)

        return _run_one_by_one(
            todo, progress, evaluator_for, _note(execution, evaluator.workers)
        )


def _ignore_stop_signals() -> None:
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


def _interrupt_once(signum: int, frame: Any) -> None:
    # The terminal, the parent and a scheduler may all signal: stop once, then
    # let the run write its outputs in peace.
    _ignore_stop_signals()
    interrupt(signum, frame)


def _child(group: list[RunSpec], note: dict[str, Any], messages: Any) -> None:
    """Runs in a process of their own, joined if several; everything they say
    goes to ``messages``."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, _interrupt_once)
    # One process per core: BLAS threads in k-means would only oversubscribe.
    limit_threads()
    if len(group) > 1:
        try:
            results = _run_group(
                group,
                note,
                lambda spec, g: messages.put(("generation", spec.name, g)),
            )
        except KeyboardInterrupt:  # before the runs started or once they ended
            results = [_interrupted(s) for s in group]
        _ignore_stop_signals()  # the runs have ended: their reports must go out
        for result in results:
            messages.put(("done", result.name, result))
        return
    spec = group[0]

    def alone() -> RunOutcome:
        with LocalEvaluator(task_spec(spec.config), workers=1) as evaluator:
            return execute_run(
                spec,
                evaluator,
                lambda g: messages.put(("generation", spec.name, g)),
                note,
            )

    outcome = _outcome(spec, alone)
    _ignore_stop_signals()
    messages.put(("done", spec.name, outcome))


class _Children:
    """Runs in child processes, at most ``slots`` at once, reporting to a queue."""

    def __init__(self, slots: int, note: dict[str, Any], progress: _Progress) -> None:
        self.messages = message_queue()
        self.slots = slots
        self.note = note
        self.progress = progress
        self.running: dict[str, tuple[Any, RunSpec]] = {}
        self.results: dict[str, RunOutcome] = {}
        self.stopping = False

    def start(self, group: Group) -> None:
        specs = [spec for spec, _ in group]
        name = specs[0].name + (f" and {len(specs) - 1} more" if len(specs) > 1 else "")
        process = start_process(_child, (specs, self.note, self.messages), name)
        for spec, done in group:
            self.running[spec.name] = (process, spec)
            self.progress.started(spec.name, done, spec.generations)

    @property
    def processes(self) -> list[Any]:
        """The processes running, each once."""
        return list({id(p): p for p, _ in self.running.values()}.values())

    def poll(self) -> None:
        """Handles one message, or looks for children that died without one."""
        try:
            kind, name, payload = self.messages.get(timeout=POLL_SECONDS)
        except queue.Empty:
            for name, (process, spec) in list(self.running.items()):
                if not process.is_alive():
                    process.join()
                    del self.running[name]
                    self.results[name] = RunOutcome(
                        name,
                        run_status(spec).generations_done,
                        False,
                        f"the run's process ended with exit code {process.exitcode} "
                        "and no report",
                    )
                    self.progress.ended(name, False)
            return
        if kind == "generation":
            spec = self.running[name][1]
            self.progress.generation(name, payload, spec.generations)
        elif kind == "done":
            process, _ = self.running.pop(name)
            if all(p is not process for p, _ in self.running.values()):
                process.join()
            self.results[name] = payload
            self.progress.ended(name, payload.finished)
            self.stopping = self.stopping or payload.interrupted or payload.system

    def interrupt(self) -> None:
        """Asks every running child to stop (they checkpoint atomically)."""
        self.stopping = True
        for process in self.processes:
            if process.is_alive() and process.pid is not None:
                os.kill(process.pid, signal.SIGINT)


def _run_processes(
    groups: list[Group], execution: Execution, progress: _Progress
) -> list[RunOutcome]:
    children = _Children(execution.concurrent_runs, _note(execution, 1), progress)
    waiting = list(groups)
    forwarded = False
    # Stop signals set a flag rather than raise KeyboardInterrupt: raised inside
    # a read of the children's queue, it could lose a child's report or cut it
    # in half.
    signalled = threading.Event()
    with stop_signals_to(lambda signum, frame: signalled.set()):
        try:
            while waiting or children.running:
                try:
                    while (
                        waiting
                        and not children.stopping
                        and len(children.processes) < children.slots
                    ):
                        children.start(waiting.pop(0))
                    children.poll()
                except KeyboardInterrupt:
                    signalled.set()
                if signalled.is_set() and not forwarded:
                    forwarded = True
                    children.interrupt()
                if children.stopping:
                    # Runs not started yet are stopped too (even when every
                    # running child had finished before the signal): the
                    # session says so.
                    for group in waiting:
                        for spec, done in group:
                            children.results[spec.name] = RunOutcome(
                                spec.name, done, finished=False, interrupted=True
                            )
                    waiting.clear()
        finally:
            for process in children.processes:
                process.terminate()
                process.join()
            children.messages.close()
    return list(children.results.values())


def _log_session(root: Path, entry: dict[str, Any]) -> None:
    """Appends one task's timings of this session to the study log."""
    with open(root / LOG_FILE, "a") as f:
        f.write(json.dumps(entry) + "\n")
