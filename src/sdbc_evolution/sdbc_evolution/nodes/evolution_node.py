"""``evolution_node``: an evolutionary experiment as a ROS 2 node.

The node runs the same experiment as the command line (``sdbc-evolve``): the same
configuration files and overrides, resolved by the same function
(:func:`sdbc_evolution.run.request.resolve_config`), the same runner
(:class:`sdbc_evolution.run.experiment.Experiment`), the same output directory,
checkpoints and ``resume``. After every generation it publishes its
statistics on ``generation_stats`` (sdbc_msgs/GenerationStats) and the generation's
best genome on ``best_genome`` (std_msgs/Float64MultiArray, latched).

Where the trials run is the ``evaluator`` parameter:

- ``local``: the engine, in this machine's processes (``workers``), as the command
  line does;
- ``live``: through the live graph (:class:`~sdbc_evolution.graph.live_evaluator.
  LiveEvaluator`): for each genome the node sets the controllers' ``genome``
  parameters, asks the simulator for the trials, and builds the SDBC vectors from
  the ``task_state`` topic. Same results as ``local``, to round-off; much slower.
  With ``graph_namespaces`` naming several simulator graphs (``sdbc-graph`` with
  ``graphs: K`` starts them in ``graph_0`` ... and sets it), each generation's
  genomes are spread over them; the results are those of one graph.

The task may be another system's (a task this project's engine does not have,
run by another simulator or by robots, see the contract in docs/ros2.md): the node then
needs the ``robots`` and ``genome_length`` parameters, runs ``live`` only, and
learns the length of the task-specific characterisation and the names of the SDBC
dimensions from a first trial (genome all zeros, seed 0) before the run starts.

Before the run directory exists, the node makes ``sdbc-evolve``'s checks
(:func:`~sdbc_evolution.run.request.check_before_run`: the task's settings, the
memory, one trial in process whose values must keep to the contract), so a
task that breaks it is a bad parameter (exit status 2) and leaves nothing; the
first trial of another system's task is checked the same way.

The current best can be watched live: the ``replay_best`` service (std_srvs/Trigger)
runs it once on the graph (controllers and simulator), and the ``replay_best``
parameter does so after every generation.

The graph's task is named once, by the ``task`` and ``task_config`` parameters that
``sdbc-graph`` gives every node; they take precedence over the experiment
configuration's. The physics model is the configuration's (``evaluation.physics``);
a live graph whose simulator runs another (its ``physics_model`` parameter) is
refused when the node connects to it.

Usage::

    evolution_node --ros-args -p experiment_config:=configs/quickstart.yaml \\
        -p output:=results/live -p evaluator:=live -p generations:=5
"""

from __future__ import annotations

import dataclasses
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from rcl_interfaces.msg import IntegerRange, ParameterDescriptor
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.parameter import Parameter
from sdbc_sim.nodes.interface import (
    BEST_GENOME_TOPIC,
    DISPLAY_QOS,
    EVOLUTION_NODE,
    GENERATION_STATS_TOPIC,
    LATCHED_QOS,
    REPLAY_BEST_SERVICE,
    parse_task_config,
)
from sdbc_sim.nodes.parameters import CheckedNode
from sdbc_sim.nodes.startup import NodeProgram, Startup, run_node_program
from sdbc_sim.task import Task
from sdbc_sim.tasks import available_tasks, find_task
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from std_srvs.srv import Trigger

from sdbc_evolution.characterise.evaluation import SDBC, TASK
from sdbc_evolution.characterise.sdbc import sdbc_dimension_names
from sdbc_evolution.graph.client import (
    GraphClient,
    GraphClientError,
    Stopped,
    check_live_characterisations,
)
from sdbc_evolution.graph.live_evaluator import LiveEvaluator
from sdbc_evolution.run.checkpoint import CheckpointError
from sdbc_evolution.run.config import ConfigError, ExperimentConfig
from sdbc_evolution.run.evaluators import (
    Evaluation,
    Evaluator,
    TaskInfo,
    check_first_trial,
    make_evaluator,
)
from sdbc_evolution.run.experiment import Experiment, task_spec
from sdbc_evolution.run.processes import available_cores
from sdbc_evolution.run.request import (
    ConfigRequest,
    check_before_run,
    default_out,
    resolve_config,
)
from sdbc_evolution.run.results import GenerationRecord
from sdbc_msgs.msg import GenerationStats

EVALUATORS = ("local", "live")
"""Values of the ``evaluator`` parameter."""
TREATMENT_NAMES = {"fit": "Fit", "ns-ts": "NS-TS", "ns-sd": "NS-SD", "ns-sd+": "NS-SD+"}
"""The paper's names of the treatments, as GenerationStats carries them."""
DEFAULT_GRAPH_TIMEOUT = 60.0
"""Seconds to wait for the live graph (simulator, controllers) to answer."""
_Value = TypeVar("_Value", bool, int, float, str)
"""The type of a parameter, given by its default."""
STOP_WAIT = 5.0
"""Seconds the experiment thread gets to stop after Ctrl-C."""


class EvolutionNode(CheckedNode):
    """Runs one experiment and publishes its progress.

    Parameters (ROS), all read-only:
        task, task_config: The graph's task (empty task: the configuration's).
        experiment_config: YAML experiment configuration (empty: quick start).
        output: Results directory (empty: ``results/<task>-<treatment>-seed<s>``).
        resume: Continue the run in ``output`` from its checkpoint.
        evaluator: ``local`` or ``live``.
        workers: Local worker processes (0: every core).
        generations, population, trials: Overrides (0: the configuration's).
        seed: Override of the run's seed (-1: the configuration's).
        treatment: Override of the treatment (empty: the configuration's).
        replay_best: Replay each generation's best live on the graph.
        replay_seed: Seed of the replayed trials.
        graph_timeout: Seconds to wait for the live graph.
        graph_namespaces: Namespaces of the simulator graphs to evaluate on,
            relative to the node's (unset: the graph in the node's own
            namespace).
        robots, genome_length: For a task that is not this project's: the
            number of robots (controllers) and of genes (0: the task's).
        exit_when_done: Leave when the run is complete (else keep serving
            ``replay_best``).

    Raises:
        ValueError: A bad parameter or configuration, naming it.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(EVOLUTION_NODE, **kwargs)
        p = self._declare
        self.task_name = p("task", "", "Task of the graph (empty: the config's)")
        task_config = p("task_config", "", "YAML mapping of task setting overrides")
        config_path = p("experiment_config", "", "Experiment YAML (empty: quick start)")
        output = p("output", "", "Results directory (empty: results/<name>)")
        resume = p("resume", False, "Continue the run in output from its checkpoint")
        self.evaluator_name = p("evaluator", "local", "Where trials run: local or live")
        workers = p("workers", 0, "Local worker processes (0: every core)", minimum=0)
        overrides = {
            name: p(name, 0, f"Override of {name} (0: the config's)", minimum=0)
            for name in ("generations", "population", "trials")
        }
        seed = p(
            "seed", -1, "Override of the run's seed (-1: the config's)", minimum=-1
        )
        treatment = p(
            "treatment", "", "Override of the treatment (empty: the config's)"
        )
        self.replay_after_generation = p(
            "replay_best", False, "Replay each generation's best on the live graph"
        )
        self.replay_seed = p("replay_seed", 0, "Seed of replayed trials", minimum=0)
        self.graph_timeout = p(
            "graph_timeout", DEFAULT_GRAPH_TIMEOUT, "Seconds to wait for the graph"
        )
        self.exit_when_done = p("exit_when_done", True, "Leave when the run is done")
        self.graph_namespaces = self._declare_namespaces()
        self.robots = p(
            "robots", 0, "Robots of another system's task (0: the task's)", minimum=0
        )
        self.genome_length = p(
            "genome_length",
            0,
            "Genes of another system's task (0: the task's)",
            minimum=0,
        )
        if self.evaluator_name not in EVALUATORS:
            raise ValueError(
                f"parameter evaluator: {self.evaluator_name!r} is not one of "
                f"{', '.join(EVALUATORS)}"
            )
        if not (np.isfinite(self.graph_timeout) and self.graph_timeout > 0):
            raise ValueError(
                f"parameter graph_timeout: must be positive, got {self.graph_timeout}"
            )
        request = ConfigRequest(
            config=Path(config_path) if config_path else None,
            resume=resume,
            out=Path(output) if output else None,
            task=self.task_name or None,
            treatment=treatment or None,
            generations=overrides["generations"] or None,
            population=overrides["population"] or None,
            trials=overrides["trials"] or None,
            seed=None if seed < 0 else seed,
        )
        try:
            if self.task_name:
                # The graph names the task for every node, with its settings.
                request = dataclasses.replace(
                    request, task_config=parse_task_config(task_config)
                )
            config = resolve_config(request)
        except (ConfigError, CheckpointError, ValueError) as error:
            raise ValueError(str(error)) from None
        self.config: ExperimentConfig = config
        self.task_name = config.task
        self.out = request.out if request.out is not None else default_out(config)
        self.resume = resume
        self.workers = workers or None
        self.spec = task_spec(config)
        self.task = self._build_task()
        self.info: TaskInfo | None = None
        if self.task is not None:
            # sdbc-evolve's checks, before a run directory exists: the memory
            # (live: the trials are the graph's), a first trial in process.
            local = available_cores() if self.workers is None else self.workers
            self.info = check_before_run(
                config, 1 if self.evaluator_name == "live" else local
            )
        self.stop = threading.Event()
        self.finished = threading.Event()
        self.complete = False  # every generation done (not only stopped)
        self.failure: str | None = None
        self.best_genome: np.ndarray | None = None
        self.best_generation = -1
        self._graph_clients: list[GraphClient] = []
        self._client_lock = threading.Lock()
        self._stats = self.create_publisher(
            GenerationStats, GENERATION_STATS_TOPIC, DISPLAY_QOS
        )
        self._best = self.create_publisher(
            Float64MultiArray, BEST_GENOME_TOPIC, LATCHED_QOS
        )
        self.create_service(
            Trigger,
            REPLAY_BEST_SERVICE,
            self._serve_replay,
            callback_group=MutuallyExclusiveCallbackGroup(),
        )

    def _declare(
        self, name: str, default: _Value, description: str, minimum: int | None = None
    ) -> _Value:
        descriptor = ParameterDescriptor(description=description, read_only=True)
        if minimum is not None:
            descriptor.integer_range = [
                IntegerRange(from_value=minimum, to_value=2**62)
            ]
        return self.declare_parameter(name, default, descriptor).value

    def _declare_namespaces(self) -> tuple[str, ...]:
        """The ``graph_namespaces`` parameter, checked: distinct ROS 2 names."""
        from sdbc_evolution.graph.graph_file import GraphError, check_namespace

        descriptor = ParameterDescriptor(
            description=(
                "Namespaces of the simulator graphs to evaluate on (unset: the "
                "node's own)"
            ),
            read_only=True,
        )
        value = self.declare_parameter(
            "graph_namespaces", Parameter.Type.STRING_ARRAY, descriptor
        ).value
        if value is None:
            return ("",)
        try:
            names = tuple(check_namespace(str(ns)) for ns in value)
        except GraphError as error:
            raise ValueError(f"parameter graph_namespaces: {error}") from None
        if not names or len(set(names)) != len(names):
            raise ValueError(
                f"parameter graph_namespaces: need distinct namespaces, got {value}"
            )
        return names

    def _build_task(self) -> Task | None:
        """This project's task, checked against ``robots`` and ``genome_length``;
        None for another system's task, which must then run live with both set.

        Raises:
            ValueError: Naming the parameter at odds with the task.
        """
        if find_task(self.spec.name) is None:
            known = available_tasks()
            if self.evaluator_name != "live":
                raise ValueError(
                    f"task {self.spec.name!r} is not one of this project's "
                    f"({', '.join(sorted(known))}): it can only be evaluated live "
                    "(evaluator:=live), by the system that runs it"
                )
            if self.robots < 1 or self.genome_length < 1:
                raise ValueError(
                    f"task {self.spec.name!r} is not one of this project's: parameters "
                    f"robots and genome_length must be set (got robots {self.robots}, "
                    f"genome_length {self.genome_length})"
                )
            return None
        task = self.spec.build()
        for name, given, actual in (
            ("robots", self.robots, task.layout.n_controlled),
            ("genome_length", self.genome_length, task.genome_length),
        ):
            if given and given != actual:
                raise ValueError(
                    f"parameter {name}: {given}, but task {self.spec.name!r} has "
                    f"{actual}"
                )
        return task

    def task_info(self, evaluator: Evaluator) -> TaskInfo:
        """The task's sizes and SDBC names: from the task, or for another system's
        task from a first trial on the live graph."""
        if self.info is not None:
            return self.info
        client = self.graph_client()
        with client.lock:
            client.set_genome(np.zeros(self.genome_length))
            trial = client.run_trial(0)
        # What probe_task checks of this project's tasks, before the run exists.
        check_first_trial(
            Evaluation(
                fitness=np.array([trial.fitness]),
                trial_fitness=np.array([[trial.fitness]]),
                behaviours={TASK: trial.characterisation[None], SDBC: trial.sdbc[None]},
            ),
            self.spec,
        )
        # A declared treatment's SDBC options name their dimensions from the task
        # description, which the first trial's messages taught the client.
        declared = check_live_characterisations(self.spec.characterisations)
        description = client.description
        if declared and description is None:
            raise GraphClientError(
                "the first trial taught no task description: a declared SDBC "
                "cannot name its dimensions"
            )
        info = TaskInfo(
            name=self.spec.name,
            genome_length=self.genome_length,
            characterisation_size=int(trial.characterisation.shape[0]),
            sdbc_names=client.sdbc_names,
            behaviour_names={
                spec.key: sdbc_dimension_names(description, spec.options)
                for spec in declared
                if description is not None
            },
        )
        self.get_logger().info(
            f"task {info.name}: learnt from a first trial: {trial.length} steps, "
            f"{info.characterisation_size} characterisation values, "
            f"{len(info.sdbc_names)} SDBC dimensions"
        )
        return info

    def graph_client(self) -> GraphClient:
        """The client of the (first) live graph, connected on first use; replays
        and a foreign task's first trial run there.

        Raises:
            GraphClientError: If the graph does not come up in time, or runs
                another task.
        """
        return self.graph_clients()[0]

    def graph_clients(self) -> list[GraphClient]:
        """A client per graph of ``graph_namespaces``, created and connected on
        first use.

        Raises:
            GraphClientError: If a graph does not come up in time, or runs
                another task.
        """
        with self._client_lock:
            if not self._graph_clients:
                clients = [
                    GraphClient(
                        self,
                        self.task,
                        self.spec.name,
                        dict(self.spec.overrides),
                        timeout=self.graph_timeout,
                        stop=self.stop,
                        n_robots=self.robots or None,
                        physics=self.spec.physics,
                        namespace=namespace,
                    )
                    for namespace in self.graph_namespaces
                ]
                for client in clients:
                    client.wait_for_graph()
                self._graph_clients = clients
            return self._graph_clients

    def make_evaluator(self) -> Evaluator:
        """The evaluator the ``evaluator`` parameter names."""
        if self.evaluator_name == "live":
            return LiveEvaluator(self.spec, self.graph_clients())
        return make_evaluator(self.spec, workers=self.workers)

    def run(self) -> None:
        """Runs the experiment to its end (or until :attr:`stop`); the body of
        the experiment thread."""
        try:
            with self.make_evaluator() as evaluator:
                info = self.task_info(evaluator)
                if self.resume:
                    experiment = Experiment.resume(
                        self.config, self.out, evaluator, info
                    )
                else:
                    experiment = Experiment.create(
                        self.config, self.out, evaluator, info
                    )
                self.get_logger().info(
                    f"{self.config.task} {self.config.treatment.name}: "
                    f"{experiment.generations} generations into {self.out} "
                    f"({self.evaluator_name} evaluation)"
                )
                started = time.monotonic()
                with experiment:  # releases the run directory's lock
                    while not experiment.finished and not self.stop.is_set():
                        population = experiment.state.population
                        record = experiment.step()
                        self._publish(experiment, record, population, started)
                        if self.replay_after_generation:
                            self._replay_or_stop_replaying()
                    self.complete = experiment.finished
            if self.complete:
                self.get_logger().info(f"run complete: results in {self.out}")
        except Exception as err:  # the thread's failure must reach the exit status
            if not self.stop.is_set():
                self.failure = f"{type(err).__name__}: {err}"
                self.get_logger().error(f"run failed: {self.failure}")
        finally:
            self.finished.set()

    def _publish(
        self,
        experiment: Experiment,
        record: GenerationRecord,
        population: np.ndarray,
        started: float,
    ) -> None:
        genome = population[record.best_index]
        self.best_genome, self.best_generation = genome.copy(), record.generation
        stats = GenerationStats(
            experiment=self.out.name,
            task=self.config.task,
            treatment=TREATMENT_NAMES.get(
                self.config.treatment.name, self.config.treatment.name
            ),
            best_fitness=record.best_fitness,
            mean_fitness=record.mean_fitness,
            median_fitness=record.median_fitness,
            best_novelty=float(np.nan_to_num(record.best_novelty, nan=0.0)),
            best_genome=genome.tolist(),
            archive_size=record.archive_size,
            wall_time=time.monotonic() - started,
            generation=record.generation,
        )
        if record.weights is not None:
            stats.weights = np.asarray(record.weights, dtype=float).tolist()
            stats.feature_names = list(experiment.info.sdbc_names)
        stats.header.stamp = self.get_clock().now().to_msg()
        self._stats.publish(stats)
        best = Float64MultiArray(data=genome.tolist())
        best.layout.dim = [
            MultiArrayDimension(label="genome", size=genome.shape[0], stride=1)
        ]
        self._best.publish(best)
        self.get_logger().info(
            f"generation {record.generation}: best {record.best_fitness:.4f}, "
            f"mean {record.mean_fitness:.4f}"
        )

    def replay(self) -> str:
        """Runs the current best genome once on the live graph; returns a line
        saying how it did.

        Raises:
            GraphClientError: No generation finished yet, or the graph failed.
        """
        genome, generation = self.best_genome, self.best_generation
        if genome is None:
            raise GraphClientError("no generation has finished yet: no best to replay")
        client = self.graph_client()
        with client.lock:
            client.set_genome(genome)
            trial = client.run_trial(self.replay_seed)
        line = (
            f"replay of generation {generation}'s best (seed {self.replay_seed}): "
            f"fitness {trial.fitness:.4f}, {trial.length} steps"
        )
        self.get_logger().info(line)
        return line

    def _replay_or_stop_replaying(self) -> None:
        """A replay after a generation; if the graph cannot do it, the run goes
        on without replays (they are for watching, the results do not need them)."""
        try:
            self.replay()
        except Stopped:
            raise
        except GraphClientError as error:
            self.replay_after_generation = False
            self.get_logger().error(f"replay failed, no more replays: {error}")

    def _serve_replay(
        self, request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        try:
            response.message = self.replay()
            response.success = True
        except GraphClientError as error:
            response.success, response.message = False, str(error)
        return response


def _run_experiment(startup: Startup, nodes: Sequence[EvolutionNode]) -> int:
    """Runs the experiment in a thread of its own while the executor serves the
    replay service and the graph client's answers, until it is done or Ctrl-C or
    SIGTERM asks to stop (the context stays up meanwhile: the experiment thread
    may still be publishing)."""
    node = nodes[0]
    thread = threading.Thread(target=node.run, name="experiment", daemon=True)
    thread.start()
    requested = startup.stop.requested
    try:
        while not (node.finished.is_set() and node.exit_when_done):
            if requested.is_set():
                break
            startup.executor.spin_once(timeout_sec=0.2)
    finally:
        node.stop.set()
        thread.join(STOP_WAIT)
    if node.failure:
        return 1
    if node.complete:
        if requested.is_set():
            print(
                f"evolution_node: run complete: results in {node.out}", file=sys.stderr
            )
    else:
        print(
            f"evolution_node: interrupted; resume with resume:=true output:={node.out}",
            file=sys.stderr,
        )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """The ``evolution_node`` program: runs the experiment its parameters name; the exit
    status."""
    return run_node_program(
        NodeProgram(
            name="evolution_node",
            make_nodes=lambda startup: [EvolutionNode()],
            serve=_run_experiment,
            # The experiment's own threads wait; these serve the graphs' answers.
            threads=4,
        ),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
