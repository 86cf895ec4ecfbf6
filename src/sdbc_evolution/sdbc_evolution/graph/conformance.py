"""A running simulator checked against the contract of evolution through another
simulator (docs/ros2.md): ``sdbc-conformance --live TASK``.

The checks drive the graph as the evolution node's live evaluation does, through a
:class:`~sdbc_evolution.graph.client.GraphClient`, so what passes here is what a
live run relies on; each failure is one line naming the problem. In order
(:data:`LIVE_CHECKS`):

- ``graph``: the simulator's ``run_trial`` service, a controller per robot and a
  publisher of ``task_state`` are there, one simulator alone offers the service,
  and the simulator's ``task`` and ``task_config`` parameters name the task and
  settings asked for;
- ``genomes``: every robot's controller takes a genome of the task's length (a
  zero genome and random ones in [-1, 1]);
- ``trials``: every trial of each genome (:data:`LIVE_GENOMES` x
  :data:`LIVE_SEEDS`) is answered with ``success``, and its task state arrives
  whole: steps 1 to the answer's ``length`` in order, the last with ``done``,
  every message fitting one task description (the same groups with the same
  fields, each group's size within its ``min_size`` and ``max_size``, entity
  states of the declared attributes, finite values); for a task of this project
  the description is the task's, for another system's the first trial's;
- ``ranges``: every trial's fitness lies in the task's ``fitness_range`` for a
  task of this project, in [0, 1] (``FITNESS_RANGE``) for another system's, and
  every value of its task-specific characterisation in [0, 1]
  (``CHARACTERISATION_RANGE``; both of :mod:`sdbc_evolution.run.evaluators`,
  what a live run refuses), every trial
  has as many characterisation values (as many as its names, when it names
  them, and as the task's own for a task of this project, whose trials also end
  within ``max_steps``), and every SDBC vector is finite.

Trial faults that a run would stop on are found here in a few trials, with the
simulator named; what a trial is worth as behaviour is not judged.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from sdbc_sim.nodes.startup import keep_dds_on_loopback
from sdbc_sim.task import Task
from sdbc_sim.tasks import find_task, make_task

from sdbc_evolution.graph.client import GraphClient, GraphClientError, LiveTrial
from sdbc_evolution.run.evaluators import (
    CHARACTERISATION_RANGE,
    TaskSpec,
    allowed,
    first_outside,
)

LIVE_GENOMES = 2
"""Genomes tried: a zero genome, then random ones."""
LIVE_SEEDS = 2
"""Trials of each genome, seeded 0, 1, ..."""
NODE_NAME = "sdbc_conformance"
"""The checking node's name."""


class ContractBroken(GraphClientError):
    """The graph answers, but not as the contract says; the message says how."""


@dataclass(frozen=True)
class LiveTarget:
    """The graph to check.

    Attributes:
        task: The task the simulator must run (its ``task`` parameter).
        task_config: Its settings that differ from the defaults (the
            simulator's ``task_config`` parameter).
        robots: Robots (controllers); needed for another system's task.
        genome_length: Genes of a genome; needed for another system's task.
        namespace: The graph's namespace ("" for none).
        timeout: Seconds to wait for the graph and for any one answer.
        seed: Seed of the random genomes.
    """

    task: str
    task_config: dict[str, Any] = field(default_factory=dict)
    robots: int | None = None
    genome_length: int | None = None
    namespace: str = ""
    timeout: float = 60.0
    seed: int = 0


class LiveSubject:
    """A node of its own on the graph, with the client that drives it and the
    trials every check shares (run once, by the ``trials`` check); a context
    manager that starts and ends rclpy.

    Raises:
        ValueError: Another system's task without ``robots`` and
            ``genome_length``, or sizes at odds with this project's task.
    """

    def __init__(self, target: LiveTarget) -> None:
        self.target = target
        self.task: Task | None = (
            make_task(target.task, **target.task_config)
            if find_task(target.task) is not None
            else None
        )
        if self.task is not None:
            length = self.task.genome_length
            if target.genome_length not in (None, length):
                raise ValueError(
                    f"--genome-length {target.genome_length}: task {target.task!r} "
                    f"has {length} genes"
                )
            self.genome_length = int(length)
        elif target.robots is None or target.genome_length is None:
            raise ValueError(
                f"task {target.task!r} is not one of this project's: give its "
                "--robots and --genome-length"
            )
        else:
            self.genome_length = target.genome_length
        rng = np.random.default_rng(target.seed)
        self.genomes = np.vstack(
            [
                np.zeros(self.genome_length),
                rng.uniform(-1.0, 1.0, (LIVE_GENOMES - 1, self.genome_length)),
            ]
        )
        self.trials: list[tuple[int, int, LiveTrial]] | None = None
        """(genome, seed, trial) of every trial, once the ``trials`` check ran."""
        self._context: Any = None
        self._executor: MultiThreadedExecutor | None = None
        self._node: Node | None = None
        self._client: GraphClient | None = None

    @property
    def client(self) -> GraphClient:
        """The graph client (within the ``with`` block)."""
        if self._client is None:
            raise RuntimeError("live subject: used outside its with block")
        return self._client

    def __enter__(self) -> LiveSubject:
        keep_dds_on_loopback()
        self._context = rclpy.Context()
        rclpy.init(context=self._context)
        try:
            node = Node(NODE_NAME, context=self._context)
            self._node = node
            # Retries of a bad stream are said by the checks, once.
            node.get_logger().set_level(LoggingSeverity.ERROR)
            self._client = GraphClient(
                node,
                self.task,
                self.target.task,
                dict(self.target.task_config),
                timeout=self.target.timeout,
                n_robots=self.target.robots,
                namespace=self.target.namespace,
            )
            self._executor = MultiThreadedExecutor(num_threads=2, context=self._context)
            self._executor.add_node(node)
            threading.Thread(
                target=self._executor.spin, name="conformance-spin", daemon=True
            ).start()
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        if self._executor is not None:
            self._executor.shutdown()
        if self._node is not None:
            self._node.destroy_node()
        if self._context is not None:
            rclpy.try_shutdown(context=self._context)
        self._executor = self._node = self._client = None


def check_graph(subject: LiveSubject) -> str:
    """The ``graph`` check (module docstring); a summary of what passed."""
    client = subject.client
    client.wait_for_graph()
    return (
        f"a simulator running {client.task_name!r} with settings "
        f"{client.task_config}, {client.n_robots} controllers, a task_state publisher"
    )


def check_genomes(subject: LiveSubject) -> str:
    """The ``genomes`` check (module docstring); a summary of what passed."""
    for genome in subject.genomes:
        subject.client.set_genome(genome)
    return (
        f"{len(subject.genomes)} genomes of {subject.genome_length} genes taken by "
        f"{subject.client.n_robots} controllers"
    )


def check_trials(subject: LiveSubject) -> str:
    """The ``trials`` check (module docstring); a summary of what passed."""
    client, trials = subject.client, []
    for g, genome in enumerate(subject.genomes):
        client.set_genome(genome)
        for seed in range(LIVE_SEEDS):
            try:
                trials.append((g, seed, client.run_trial(seed)))
            except GraphClientError as error:
                raise ContractBroken(f"genome {g}, seed {seed}: {error}") from None
    subject.trials = trials
    lengths = [trial.length for _, _, trial in trials]
    description = client.description
    groups = "" if description is None else f", {len(description.groups)} groups"
    return (
        f"{len(trials)} trials of {min(lengths)}-{max(lengths)} steps, every step's "
        f"task state in order and of one description{groups}"
    )


def check_ranges(subject: LiveSubject) -> str:
    """The ``ranges`` check (module docstring); a summary of what passed."""
    if subject.trials is None:
        raise ContractBroken("no trials to check: the trials check did not pass")
    trials = subject.trials
    fitness_range = TaskSpec(subject.target.task).fitness_range
    sizes = {t.characterisation.shape[0] for _, _, t in trials}
    for g, seed, trial in trials:
        where = f"genome {g}, seed {seed}"
        size, names = trial.characterisation.shape[0], trial.characterisation_names
        if len(sizes) > 1:
            raise ContractBroken(
                f"{where}: {size} characterisation values, other trials "
                f"{sorted(sizes - {size})}"
            )
        if names and len(names) != size:
            raise ContractBroken(
                f"{where}: {size} characterisation values, {len(names)} names"
            )
        for label, values, bounds in (
            ("fitness", np.array([trial.fitness]), fitness_range),
            ("characterisation", trial.characterisation, CHARACTERISATION_RANGE),
            ("SDBC", trial.sdbc, None),
        ):
            outside = first_outside(values, bounds)
            if outside is not None:
                (index, *_), _ = outside
                name = "" if label == "fitness" else f" value {index}"
                if label == "characterisation" and names:
                    name = f" value {index} ({names[index]!r})"
                raise ContractBroken(
                    f"{where}: {label}{name} is {float(values[index])!r}, the "
                    f"contract says {allowed(bounds)}"
                )
        if subject.task is not None:
            _as_the_task_says(subject.task, where, trial)
    fitness = [t.fitness for _, _, t in trials]
    return (
        f"{len(trials)} trials: fitness {min(fitness):.3g}-{max(fitness):.3g}, "
        f"{sizes.pop()} characterisation values each, {trials[0][2].sdbc.shape[0]} "
        "finite SDBC values"
    )


def _as_the_task_says(task: Task, where: str, trial: LiveTrial) -> None:
    names = tuple(task.characterisation_names)
    if trial.characterisation.shape[0] != len(names):
        raise ContractBroken(
            f"{where}: {trial.characterisation.shape[0]} characterisation values, "
            f"the task has {len(names)}"
        )
    if trial.characterisation_names and trial.characterisation_names != names:
        raise ContractBroken(
            f"{where}: characterisation names {list(trial.characterisation_names)}, "
            f"the task's are {list(names)}"
        )
    if not 1 <= trial.length <= task.max_steps:
        raise ContractBroken(
            f"{where}: {trial.length} steps, the task's max_steps is {task.max_steps}"
        )


LIVE_CHECKS = {
    "graph": check_graph,
    "genomes": check_genomes,
    "trials": check_trials,
    "ranges": check_ranges,
}
"""Every live check, in the order they run."""
