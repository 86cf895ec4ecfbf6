"""Evaluators: where a generation's trials run.

Every evaluator takes genomes (G, W) and trial seeds (G, T) and returns an
:class:`Evaluation`: per controller its fitness (the engine's aggregate over its
trials) and one behaviour vector per characterisation the task spec asks for (the
task-specific one and the paper's SDBC always; see
:mod:`sdbc_evolution.characterise.registry`), each the mean over its trials, plus the
per-trial fitness. The batch is cut into chunks of whole controllers; every chunk is
one ``run_batch`` call with the characterisers observing it. Since the
engine makes a trial's result depend only on (task settings, genome, seed), chunking
and the number of workers cannot change the results, so every evaluator returns the
same arrays to the bit.

- :class:`LocalEvaluator`: this machine. One worker runs in process; more run a
  process pool (default: every core), one chunk per worker, made by
  :mod:`sdbc_evolution.run.processes` like every process of the project.
- :class:`DaskEvaluator`: a Dask cluster, for users who outgrow one machine; the
  scheduler's address as ``tcp://host:port`` or ``tls://host:port``. Its workers
  need this package importable. TLS settings come from Dask's own configuration
  (``distributed.comm.tls.*``: a Dask YAML file, or the environment variables
  ``DASK_DISTRIBUTED__COMM__TLS__CA_FILE``, ``..._CLIENT__CERT``,
  ``..._CLIENT__KEY``), or a ``distributed.security.Security`` passed in.
  Dask pickles task arguments: whoever reaches the scheduler runs code on the
  workers, so a scheduler must only be reachable by its users (TLS with client
  certificates, or a private network).

Workers build the task themselves from a :class:`TaskSpec` (name + overrides; the
physics model and fitness mean ride along), once per process, so nothing heavier
than genomes and seeds crosses process boundaries.
"""

from __future__ import annotations

import argparse
import math
import time
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from concurrent.futures import CancelledError, ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np
from sdbc_sim.fitness import controller_fitness
from sdbc_sim.limits import MAX_CONNECT_TIMEOUT, MAX_WORKERS

from sdbc_evolution.characterise.base import per_controller
from sdbc_evolution.characterise.evaluation import SDBC, TASK, Evaluation
from sdbc_evolution.characterise.registry import ALWAYS, CharacterisationSpec
from sdbc_evolution.run.config import PhysicsModel
from sdbc_evolution.run.processes import available_cores, worker_pool
from sdbc_evolution.run.stopping import raise_if_stopped

if TYPE_CHECKING:
    from sdbc_sim.engine import EngineSettings

__all__ = [
    "Evaluation",
    "Evaluator",
    "TaskInfo",
    "TaskSpec",
    "TaskFailed",
    "ValuesOutOfRange",
    "check_first_trial",
    "check_values",
]

DEFAULT_CONNECT_TIMEOUT = 10.0
"""Seconds to wait for a Dask scheduler before giving up."""
LOST_POLL_SECONDS = 0.05
"""How often a Dask evaluation looks whether its scheduler is still there."""


@dataclass(frozen=True)
class TaskSpec:
    """What a worker needs to evaluate: the task's registry name and overrides,
    the physics model, and how trials sum up into a controller's fitness.

    Attributes:
        name: Task name in the ``sdbc_sim.tasks`` registry.
        overrides: Settings that differ from the task's defaults.
        fitness_mean: "harmonic" or "arithmetic" (see ``sdbc_sim.engine.run_batch``).
        physics: The engine's physics model, "rigid" or "kinematic" (see
            ``sdbc_sim.physics.PhysicsSettings.model``).
        characterisations: Characterisations to compute besides the task-specific
            one and the paper's SDBC, which every evaluation carries.
    """

    name: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    fitness_mean: str = "harmonic"
    physics: PhysicsModel = "rigid"
    characterisations: tuple[CharacterisationSpec, ...] = ()

    @cached_property
    def fitness_range(self) -> tuple[float, float]:
        """Where the task's trial fitness lies: its class's ``fitness_range``, or
        :data:`FITNESS_RANGE` for a name no registered task has (a task of an
        outside simulator's)."""
        from sdbc_sim.tasks import UnknownTask, resolve_task

        try:
            low, high = resolve_task(self.name).fitness_range
        except UnknownTask:
            return FITNESS_RANGE
        return (float(low), float(high))

    def all_characterisations(self) -> tuple[CharacterisationSpec, ...]:
        """Every characterisation an evaluation carries, each once, by key."""
        unique: dict[str, CharacterisationSpec] = {}
        for spec in (*ALWAYS, *self.characterisations):
            unique.setdefault(spec.key, spec)
        return tuple(unique.values())

    def evaluates_like(self, other: TaskSpec) -> bool:
        """Whether evaluations for ``other`` are the same arrays as for this
        spec: the same task, settings, physics and fitness mean, and the same
        characterisations once the two every evaluation carries are counted."""
        return (
            self.key(),
            self.fitness_mean,
            self.physics,
            [c.key for c in self.all_characterisations()],
        ) == (
            other.key(),
            other.fitness_mean,
            other.physics,
            [c.key for c in other.all_characterisations()],
        )

    def key(self) -> tuple[str, str]:
        """A hashable identity of the task, for caching built tasks."""
        return (self.name, repr(sorted(self.overrides.items())))

    def build(self) -> Any:
        """The task object (raises ValueError for an unknown name or bad settings)."""
        from sdbc_sim.tasks import make_task

        return make_task(self.name, **dict(self.overrides))

    def engine_settings(self) -> EngineSettings:
        """The engine's settings for this spec's physics model (raises
        ValueError for an unknown model)."""
        from sdbc_sim.engine import EngineSettings
        from sdbc_sim.physics import PhysicsSettings

        return EngineSettings(physics=PhysicsSettings(model=self.physics))


@dataclass(frozen=True)
class TaskInfo:
    """What the GA needs to know about a task.

    Attributes:
        name: Task name.
        genome_length: W, the number of network weights.
        characterisation_size: C, length of the task-specific characterisation.
        sdbc_names: Names of the D dimensions of the raw SDBC vector.
        behaviour_names: Characterisation key -> names of its dimensions, for
            every characterisation the evaluations carry.
    """

    name: str
    genome_length: int
    characterisation_size: int
    sdbc_names: tuple[str, ...]
    behaviour_names: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    @classmethod
    def of(cls, spec: TaskSpec) -> TaskInfo:
        """Builds the task once and reads its sizes and dimension names.

        Raises:
            ValueError: A characterisation cannot be made for this task.
        """
        task = spec.build()
        names = {c.key: c.build().names(task) for c in spec.all_characterisations()}
        return cls(
            name=spec.name,
            genome_length=int(task.genome_length),
            characterisation_size=int(task.characterisation_size),
            sdbc_names=names[SDBC],
            behaviour_names=names,
        )

    def names_of(self, key: str) -> tuple[str, ...]:
        """Dimension names of the characterisation ``key``."""
        if key in self.behaviour_names:
            return tuple(self.behaviour_names[key])
        if key == SDBC:
            return self.sdbc_names
        if key == TASK:
            return tuple(f"{TASK} {i}" for i in range(self.characterisation_size))
        raise KeyError(f"task {self.name!r}: no characterisation {key!r} was computed")


_TASKS: dict[tuple[str, str], Any] = {}


def evaluate_chunk(
    spec: TaskSpec, genomes: np.ndarray, seeds: np.ndarray
) -> Evaluation:
    """Runs one chunk of controllers through the engine (in whatever process).

    Args:
        spec: The task to build (cached per process).
        genomes: (g, W) genomes.
        seeds: (g, T) int64 trial seeds.
    """
    from sdbc_sim.engine import run_batch

    key = spec.key()
    if key not in _TASKS:
        _TASKS[key] = spec.build()
    task = _TASKS[key]
    characterisers = {c.key: c.build() for c in spec.all_characterisations()}
    result = run_batch(
        task,
        genomes,
        seeds,
        observers=tuple(c for c in characterisers.values() if c.observes),
        fitness_mean=spec.fitness_mean,
        settings=spec.engine_settings(),
    )
    trials = seeds.shape[1]
    return Evaluation(
        fitness=np.asarray(result.controller_fitness, dtype=np.float64),
        trial_fitness=np.asarray(result.fitness, dtype=np.float64),
        behaviours={
            k: np.asarray(c.controller_vectors(result, trials), dtype=np.float64)
            for k, c in characterisers.items()
        },
    )


FITNESS_RANGE = (0.0, 1.0)
"""Where the contract of an outside simulator (docs/ros2.md, "Evolution through
another simulator: the contract") puts every trial's fitness, and a task's
(``sdbc_sim.task.Task.fitness_range``) unless it declares another."""
CHARACTERISATION_RANGE = (0.0, 1.0)
"""Where the contract puts every value of the task-specific characterisation."""


class TaskFailed(ValueError):
    """A task that fails its first trial; the message says how."""


def probe_task(spec: TaskSpec, info: TaskInfo) -> None:
    """Runs one trial of a zero genome in this process, with every
    characterisation of ``spec`` observing and its values checked
    (:func:`check_values`), so that a task that cannot run (a task state that
    does not fit its description, values outside the contract) is refused
    before a run directory exists, not in the middle of its first generation.

    Raises:
        TaskFailed: Naming the task and what its trial did.
    """
    genome = np.zeros((1, info.genome_length))
    try:
        evaluation = evaluate_chunk(spec, genome, np.zeros((1, 1), dtype=np.int64))
    except (ValueError, TypeError, IndexError, KeyError) as error:
        raise TaskFailed(
            f"task {spec.name!r} fails its first trial: {type(error).__name__}: {error}"
        ) from None
    check_first_trial(evaluation, spec)


def check_first_trial(evaluation: Evaluation, spec: TaskSpec) -> None:
    """:func:`check_values` of a trial run before the run directory exists (by
    :func:`probe_task`, or on another system's simulator), said as such.

    Raises:
        TaskFailed: Naming the first bad value.
    """
    try:
        check_values(evaluation, spec)
    except ValuesOutOfRange as error:
        raise TaskFailed(f"a first trial: {error}") from None


def chunk_bounds(n: int, chunks: int) -> list[tuple[int, int]]:
    """Splits range(n) into at most ``chunks`` consecutive, nearly equal slices."""
    chunks = max(1, min(chunks, n))
    edges = [round(i * n / chunks) for i in range(chunks + 1)]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _check_batch(
    genomes: np.ndarray, seeds: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    genomes = np.asarray(genomes, dtype=np.float64)
    seeds = np.asarray(seeds)
    if genomes.ndim != 2 or seeds.ndim != 2 or seeds.shape[0] != genomes.shape[0]:
        raise ValueError(
            f"genomes (G, W) and seeds (G, T) disagree: {genomes.shape} and "
            f"{seeds.shape}"
        )
    if seeds.dtype != np.int64:
        raise ValueError(f"seeds must be int64, got {seeds.dtype}")
    return genomes, seeds


class ValuesOutOfRange(ValueError):
    """An evaluation whose values break the contract: the run stops before the
    generation is scored, and its checkpoint (the previous generation's) is
    intact. The message names the value, the genome and the trial."""


def check_values(evaluation: Evaluation, spec: TaskSpec) -> None:
    """Refuses an evaluation of the task ``spec`` with a trial fitness outside the
    task's range (:attr:`TaskSpec.fitness_range`), a
    task-specific characterisation value outside :data:`CHARACTERISATION_RANGE`,
    or a NaN or infinite value in any characterisation.

    Why stop rather than warn or drop the trial: every such value comes from a
    task or simulator that breaks its contract (a negative fitness, which the
    harmonic mean floors at 1e-4 so that evolution gets no signal; an outside
    simulator answering 20), so every later generation would be selected on it;
    dropping trials would bias the run silently. Stopping costs one generation,
    which resume repeats once the task is fixed.

    Raises:
        ValuesOutOfRange: Naming the first bad value, where it is, and the task.
    """
    checks: list[tuple[str, np.ndarray, tuple[float, float] | None]] = [
        ("trial fitness", evaluation.trial_fitness, spec.fitness_range)
    ]
    for key, values in evaluation.behaviours.items():
        bounds = CHARACTERISATION_RANGE if key == TASK else None
        checks.append((f"characterisation {key!r}", values, bounds))
    for label, values, bounds in checks:
        values = np.asarray(values, dtype=np.float64)
        outside = first_outside(values, bounds)
        if outside is None:
            continue
        where, count = outside
        position = (
            f"genome {where[0]}, trial {where[1]}"
            if label == "trial fitness"
            else f"genome {where[0]}, dimension {where[1]}"
        )
        raise ValuesOutOfRange(
            f"task {spec.name!r} returned {label} {float(values[where])!r} at "
            f"{position} "
            f"({count} of {values.size} values), the contract says "
            f"{allowed(bounds)}: fix the task or simulator (docs/limits.md), then "
            "resume"
        )


def first_outside(
    values: np.ndarray, bounds: tuple[float, float] | None
) -> tuple[tuple[int, ...], int] | None:
    """Where the first value of ``values`` that is not finite or outside
    ``bounds`` (None: finite is enough) is, and how many such values there are;
    None if there are none."""
    values = np.asarray(values, dtype=np.float64)
    bad = ~np.isfinite(values)
    if bounds is not None:
        bad |= (values < bounds[0]) | (values > bounds[1])
    if not bad.any():
        return None
    return tuple(int(i) for i in np.argwhere(bad)[0]), int(bad.sum())


def allowed(bounds: tuple[float, float] | None) -> str:
    """What ``bounds`` allow, in words: ``in [0, 1]``, or ``finite`` for None."""
    return "finite" if bounds is None else f"in [{bounds[0]:g}, {bounds[1]:g}]"


class Evaluator(ABC):
    """Evaluates genomes in trials; every implementation gives the same results.

    Whatever runs the trials (this machine, a Dask cluster, the live graph and
    an outside simulator), :meth:`evaluate` checks what comes back with
    :func:`check_values`.
    """

    spec: TaskSpec

    @property
    @abstractmethod
    def workers(self) -> int:
        """How many chunks a batch is cut into."""

    @abstractmethod
    def _run(
        self, genomes: np.ndarray, seeds: np.ndarray, bounds: list[tuple[int, int]]
    ) -> list[Evaluation]:
        """Evaluates the chunks ``genomes[a:b]`` for (a, b) in ``bounds``, in order."""

    def evaluate(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        """Evaluates G genomes, genome g in the trials seeded by ``seeds[g]``.

        Args:
            genomes: (G, W) float64 genomes.
            seeds: (G, T) int64 trial seeds.

        Raises:
            ValuesOutOfRange: A value breaks the contract (:func:`check_values`).
            KeyboardInterrupt: A stop signal came, in the batch or before it
                (:func:`~sdbc_evolution.run.stopping.raise_if_stopped`).
        """
        evaluation = self._unchecked(*_check_batch(genomes, seeds))
        check_values(evaluation, self.spec)
        return evaluation

    def _unchecked(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        """:meth:`evaluate` without the values' check, on a checked batch."""
        bounds = chunk_bounds(genomes.shape[0], self.workers)
        evaluations = self._run(genomes, seeds, bounds)
        # A stop signal in the batch whose KeyboardInterrupt was lost.
        raise_if_stopped()
        return Evaluation.concatenate(evaluations)

    def evaluate_together(
        self, requests: Sequence[tuple[np.ndarray, np.ndarray]]
    ) -> list[Evaluation]:
        """Evaluates several requests, (genomes (G, W), seeds (G, T)) each, with
        T free to differ between them; each comes back as :meth:`evaluate` would
        give it, to the bit.

        A batch of few trials pays the engine's cost per step for few robots: a
        run's re-evaluation (10 trials) alone cost about a quarter of its
        generation's evaluation (``docs/speed.md``). When every characterisation
        is the mean of its trials (``Characteriser.mean_of_trials``), the trials
        of all requests run as one batch, a trial per row, and each request's
        controller fitness and vectors are summed up from its own trials with
        the functions and the layout the engine and the characterisers use.
        Otherwise each request is evaluated on its own.

        Raises:
            ValueError: A request's genomes and seeds disagree.
            ValuesOutOfRange: A value breaks the contract (:func:`check_values`),
                named in the first request that holds one.
        """
        evaluations = self.unchecked_together(requests)
        for evaluation in evaluations:
            check_values(evaluation, self.spec)
        return evaluations

    def unchecked_together(
        self, requests: Sequence[tuple[np.ndarray, np.ndarray]]
    ) -> list[Evaluation]:
        """:meth:`evaluate_together` without the values' check, for a caller that
        checks each request's values on its own (``sdbc_evolution.run.joined``:
        one run's bad value must not stop the runs evaluated beside it)."""
        checked = [_check_batch(g, s) for g, s in requests]
        if len(checked) < 2 or not self.joins_requests:
            return [self._unchecked(g, s) for g, s in checked]
        joint = self._unchecked(
            np.concatenate([np.repeat(g, s.shape[1], axis=0) for g, s in checked]),
            np.concatenate([s.reshape(-1, 1) for _, s in checked]),
        )
        evaluations = []
        start = 0
        for _, s in checked:
            n, t = s.shape
            rows = slice(start, start + n * t)
            start += n * t
            trial_fitness = joint.trial_fitness[rows].reshape(n, t).copy()
            evaluations.append(
                Evaluation(
                    fitness=controller_fitness(trial_fitness, self.spec.fitness_mean),
                    trial_fitness=trial_fitness,
                    behaviours={
                        k: per_controller(v[rows], t)
                        for k, v in joint.behaviours.items()
                    },
                )
            )
        return evaluations

    @property
    def joins_requests(self) -> bool:
        """Whether :meth:`evaluate_together` runs its requests in one batch:
        when every characterisation is the mean of its trials."""
        return all(
            c.registered.part.mean_of_trials for c in self.spec.all_characterisations()
        )

    @abstractmethod
    def close(self) -> None:
        """Releases workers or connections."""

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LocalEvaluator(Evaluator):
    """Evaluates on this machine: in process with one worker, else a process pool.

    Args:
        spec: The task.
        workers: Number of processes; None means every core this process may use.
    """

    def __init__(self, spec: TaskSpec, workers: int | None = None) -> None:
        if workers is None:
            workers = available_cores()
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        if workers > MAX_WORKERS:
            raise ValueError(
                f"workers must be at most MAX_WORKERS={MAX_WORKERS}, got {workers}"
            )
        self.spec = spec
        self._workers = workers
        self._pool: ProcessPoolExecutor | None = None

    @property
    def workers(self) -> int:
        return self._workers

    def _run(
        self, genomes: np.ndarray, seeds: np.ndarray, bounds: list[tuple[int, int]]
    ) -> list[Evaluation]:
        if self._workers == 1 or len(bounds) == 1:
            return [
                evaluate_chunk(self.spec, genomes[a:b], seeds[a:b]) for a, b in bounds
            ]
        if self._pool is None:
            self._pool = worker_pool(self._workers)
        futures = [
            self._pool.submit(evaluate_chunk, self.spec, genomes[a:b], seeds[a:b])
            for a, b in bounds
        ]
        return [f.result() for f in futures]

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class SchedulerUnreachable(ConnectionError):
    """No Dask scheduler answered at the given address in time, or it has no
    workers."""


class SchedulerLost(ConnectionError):
    """The Dask scheduler went away during a run (the checkpoint is intact)."""


def _refuses(address: str, timeout: float) -> str | None:
    """ "connection refused" if nothing listens at a ``tcp://``/``tls://``
    address: Dask's own connect retries a refused port until its timeout."""
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(address)
    if parts.scheme not in ("tcp", "tls") or parts.hostname is None:
        return None
    try:
        port = parts.port
    except ValueError:
        return None
    if port is None:
        return None
    try:
        with socket.create_connection((parts.hostname, port), timeout=timeout):
            return None
    except ConnectionRefusedError:
        return "connection refused"
    except OSError:
        return None  # let Dask's connect say what it finds


def _probe_scheduler(address: str, timeout: float, security: Any) -> None:
    """Asks ``address`` who it is, giving up after ``timeout`` seconds.

    Creating a ``distributed.Client`` against a dead address leaves a half-built
    client whose clean-up blocks for twice the timeout; a bare handshake first fails
    fast and cleanly, whatever answers (or not) at the address.
    """
    import asyncio

    from distributed.comm import connect

    refused = _refuses(address, timeout)
    if refused is not None:
        raise SchedulerUnreachable(
            f"no Dask scheduler at {address!r}: {refused} (is it running? is the "
            "port right?)"
        )
    connection_args = security.get_connection_args("client")

    async def identity() -> Any:
        comm = await connect(address, timeout=timeout, **connection_args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(identity(), timeout))
    except Exception as error:  # refused, timed out, bad scheme, not Dask at all
        if isinstance(error, MemoryError):
            # dask read a non-Dask reply's first bytes as an absurd frame length.
            detail = "something answered that does not speak the Dask protocol"
        elif str(error):
            detail = f"{type(error).__name__}: {error}"
        else:
            detail = type(error).__name__
        raise SchedulerUnreachable(
            f"no Dask scheduler answered at {address!r} within {timeout:g} s ({detail})"
        ) from None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise SchedulerUnreachable(
            f"{address!r} answered, but not as a Dask scheduler: {str(reply)[:120]}"
        )


class DaskEvaluator(Evaluator):
    """Evaluates on a Dask cluster.

    Args:
        spec: The task.
        address: The scheduler, e.g. ``tcp://10.0.0.5:8786`` or ``tls://...``.
        timeout: Seconds to wait for the scheduler, and then for its first worker,
            before raising :class:`SchedulerUnreachable`.
        security: TLS settings; default: Dask's configuration (see the module
            docstring).

    Raises:
        SchedulerUnreachable: Refused, silent, not a Dask scheduler, or no
            worker within ``timeout``.
    """

    def __init__(
        self,
        spec: TaskSpec,
        address: str,
        timeout: float = DEFAULT_CONNECT_TIMEOUT,
        security: Any = None,
    ) -> None:
        require_dask()
        from distributed import Client
        from distributed.security import Security

        if not (math.isfinite(timeout) and 0 < timeout <= MAX_CONNECT_TIMEOUT):
            raise ValueError(
                f"timeout must be in (0, MAX_CONNECT_TIMEOUT={MAX_CONNECT_TIMEOUT:g}] "
                f"seconds, got {timeout:g}"
            )
        self.spec = spec
        self.address = address
        self.timeout = timeout
        security = security if security is not None else Security()
        _probe_scheduler(address, timeout, security)
        self._client = Client(
            address, timeout=timeout, security=security, set_as_default=False
        )
        try:
            self._client.wait_for_workers(1, timeout=timeout)
        except TimeoutError:
            self._client.close()
            raise SchedulerUnreachable(
                f"the Dask scheduler at {address!r} has no workers (waited "
                f"{timeout:g} s, --connect-timeout): start some with "
                f"`dask worker {address}`"
            ) from None

    @property
    def workers(self) -> int:
        try:
            threads = self._client.nthreads()
        except OSError as error:
            # Asked at the start of every generation: a scheduler that died
            # between two shows here, as a reset or closed connection.
            self._lost(type(error).__name__)
        return max(1, sum(threads.values()))

    def _run(
        self, genomes: np.ndarray, seeds: np.ndarray, bounds: list[tuple[int, int]]
    ) -> list[Evaluation]:
        futures = [
            self._client.submit(
                evaluate_chunk, self.spec, genomes[a:b], seeds[a:b], pure=False
            )
            for a, b in bounds
        ]
        self._wait(futures)
        try:
            return self._client.gather(futures)
        except (OSError, CancelledError) as error:
            # CommClosedError is an OSError; a lost scheduler cancels futures. A
            # task's own OSError comes through gather too, while the scheduler
            # still listens; a reset connection can arrive before the client has
            # noticed that the scheduler is gone, so the port is asked.
            if (
                isinstance(error, OSError)
                and self._client.status == "running"
                and _refuses(self.address, self.timeout) is None
            ):
                raise
            self._lost(type(error).__name__)
            raise  # not reached: _lost raises

    def _wait(self, futures: list[Any]) -> None:
        """Waits for ``futures``; a scheduler gone for ``timeout`` seconds raises
        :class:`SchedulerLost` (the client itself would wait for it forever)."""
        gone_since: float | None = None
        while not all(future.done() for future in futures):
            if self._client.status == "running":
                gone_since = None
            else:
                gone_since = gone_since or time.monotonic()
                if time.monotonic() - gone_since > self.timeout:
                    self._lost(f"client {self._client.status} for {self.timeout:g} s")
            time.sleep(LOST_POLL_SECONDS)

    def _lost(self, detail: str) -> NoReturn:
        raise SchedulerLost(
            f"lost the Dask scheduler at {self.address!r} ({detail}); the run's "
            "checkpoint is intact"
        )

    def close(self) -> None:
        self._client.close()


def require_dask() -> None:
    """Refuses, in one line, a Dask cluster without Dask's client installed (an
    extra of this package: a plain install evaluates locally).

    Raises:
        ValueError: ``distributed`` cannot be imported.
    """
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        raise ValueError(
            "--scheduler needs Dask's distributed, which is not installed: "
            "pip install 'sdbc_evolution[dask]'"
        )


def quiet_dask_logging() -> None:
    """Keeps Dask's client from logging tracebacks to the terminal (one per
    failed reconnection to a lost scheduler): a command says what happened in
    one line of its own. Warnings of the workers' code still come through."""
    import logging

    require_dask()
    import distributed  # noqa: F401 (sets its loggers' levels when imported)

    # distributed.batched: the client's batched stream to the scheduler, which
    # logs the closed connection with a traceback when the scheduler dies while
    # a message waits to be sent (a race: seen in 1 run of the test out of 3).
    for name in (
        "distributed.client",
        "distributed.comm",
        "distributed.core",
        "distributed.batched",
    ):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def make_evaluator(
    spec: TaskSpec,
    workers: int | None = None,
    scheduler: str | None = None,
    timeout: float = DEFAULT_CONNECT_TIMEOUT,
) -> Evaluator:
    """The evaluator a user asked for: Dask if a scheduler is given, else local."""
    if scheduler is not None:
        if workers is not None:
            raise ValueError(
                "workers and scheduler exclude each other: the Dask "
                "cluster decides its own workers"
            )
        return DaskEvaluator(spec, scheduler, timeout)
    return LocalEvaluator(spec, workers)


def check_evaluator_arguments(args: argparse.Namespace) -> None:
    """Refuses ``--workers`` and ``--connect-timeout`` beyond their limits
    (:mod:`sdbc_sim.limits`), before anything is made.

    Raises:
        ValueError: Naming the flag, its limit and the value.
    """
    workers = args.workers
    if workers is not None and workers < 1:
        raise ValueError(f"--workers: must be at least 1, got {workers}")
    if workers is not None and workers > MAX_WORKERS:
        raise ValueError(
            f"--workers: must be at most MAX_WORKERS={MAX_WORKERS}, got {workers}"
        )
    timeout = args.connect_timeout
    if not (math.isfinite(timeout) and 0 < timeout <= MAX_CONNECT_TIMEOUT):
        raise ValueError(
            f"--connect-timeout: must be in (0, MAX_CONNECT_TIMEOUT="
            f"{MAX_CONNECT_TIMEOUT:g}] seconds, got {timeout:g}"
        )


def add_evaluator_arguments(parser: argparse.ArgumentParser, workers_help: str) -> None:
    """Adds ``--workers N | --scheduler ADDRESS`` and ``--connect-timeout`` to a
    command line: where evaluations run, the same way for every command."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help=workers_help)
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="evaluate on a Dask cluster instead"
    )
    parser.add_argument(
        "--connect-timeout",
        type=float,
        default=DEFAULT_CONNECT_TIMEOUT,
        help="seconds to wait for the Dask scheduler",
    )
