"""The live graph seen from outside: genomes in, trials and their SDBCs out.

A :class:`GraphClient` lives on a node of its caller (the evolution node, a test).
It sets a genome on every robot's controller through the controllers' parameter
services (``robot_<i>/controller/set_parameters``), asks the simulator for a trial
(``run_trial``), and characterises the trial from the ``task_state`` topic with the
streaming SDBC extractor, message by message
(:class:`sdbc_evolution.sdbc.messages.MessageSdbcExtractor`): nothing of the
trajectory is kept. A trial counts only if every step's task state arrived, steps
1 to its length in order; otherwise it is run again (trials are deterministic, so
a repeat is the same trial), up to :data:`TRIAL_ATTEMPTS` times.

The client needs the task only through the messages: a task of this project gives
its description up front; for another system's task (``task=None``) the client
needs the number of robots, learns the task description from the first trial's
task state messages, and the names of the SDBC dimensions with it
(:attr:`GraphClient.sdbc_names`). What the client relies on is the contract in
docs/ros2.md ("Evolution through another simulator: the contract"): a node
``simulator`` with
``task`` and ``task_config`` parameters and the ``run_trial`` service, the
``task_state`` topic, and a controller node ``robot_<i>/controller`` per robot with
a double-array ``genome`` parameter. Those names are relative: a client given a
``namespace`` drives the graph pushed into it (``sdbc-graph --namespace``), so
several graphs share a DDS domain, each with its own client.

The caller's node must be spun by an executor in another thread (the client
waits on futures that the executor completes). The service clients share a
reentrant callback group; the task state subscription has a mutually exclusive
one, so that its messages are handled one at a time, in order of arrival.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.callback_groups import (
    MutuallyExclusiveCallbackGroup,
    ReentrantCallbackGroup,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from sdbc_sim.nodes.interface import (
    CONTROLLER_NODE,
    RUN_TRIAL_SERVICE,
    SIMULATOR_NODE,
    TASK_STATE_QOS,
    TASK_STATE_TOPIC,
    parse_task_config,
    robot_namespace,
)
from sdbc_sim.task import Task
from sdbc_sim.task_state import TaskDescription

from sdbc_evolution.characterise.evaluation import SDBC, TASK
from sdbc_evolution.characterise.registry import CharacterisationSpec
from sdbc_evolution.characterise.sdbc import OptionedSdbcExtractor
from sdbc_evolution.sdbc.characterisation import dimension_names
from sdbc_evolution.sdbc.messages import MessageSdbcExtractor
from sdbc_msgs.msg import TaskState as TaskStateMsg
from sdbc_msgs.srv import RunTrial

PHYSICS_MODEL_PARAMETER = "physics_model"
"""The simulator's parameter naming its physics model (``sdbc_sim``'s simulator
node has it; another system's need not)."""
TRIAL_ATTEMPTS = 2
"""How often a trial is run before an incomplete task state stream is an error."""
DISCOVERY_GRACE = 0.5
"""Seconds to wait after this side has discovered the graph, for the other sides
to discover this node (DDS discovery is not symmetric)."""
POLL = 0.1
"""Seconds between checks of the stop flag while waiting."""


def check_live_characterisations(
    characterisations: tuple[CharacterisationSpec, ...],
) -> tuple[CharacterisationSpec, ...]:
    """The characterisations among ``characterisations`` that the client makes
    itself: every SDBC, with any options, from the task state topic (the task's
    own and the paper's SDBC always come with a trial).

    Raises:
        ValueError: Naming a characterisation that is not an SDBC, and why: one
            that needs the robots' network inputs and outputs (the graph's sensor
            readings do not say which robots are still in play, so a count over
            them would differ from the engine's), or one of the task state that
            the client does not make.
    """
    others = []
    for spec in characterisations:
        if spec.key in (TASK, SDBC):
            continue
        if spec.kind != SDBC and spec.needs_network:
            raise ValueError(
                f"characterisation {spec.key!r} cannot be made on the live graph: it "
                "needs the robots' network inputs and outputs with which robots are "
                "in play, which the graph's topics do not carry; evaluate it with "
                "the batched engine (evaluator: local)"
            )
        if spec.kind != SDBC:
            raise ValueError(
                f"characterisation {spec.key!r} cannot be made on the live graph: "
                "the graph client makes only SDBCs from the task state topic; "
                "evaluate it with the batched engine (evaluator: local)"
            )
        others.append(spec)
    return tuple(others)


class GraphClientError(RuntimeError):
    """The live graph could not do what was asked; the message says why."""


class GenomeRejected(GraphClientError):
    """A controller rejected a genome.

    Attributes:
        robot: The robot whose controller rejected it.
        reason: The controller's reason.
    """

    def __init__(self, robot: int, reason: str) -> None:
        super().__init__(f"robot {robot}'s controller rejected the genome: {reason}")
        self.robot = robot
        self.reason = reason


class TrialFailed(GraphClientError):
    """The simulator aborted a trial, or its task state did not arrive whole."""


class Stopped(GraphClientError):
    """The client was asked to stop while waiting."""


@dataclass(frozen=True)
class LiveTrial:
    """One trial run through the live graph.

    Attributes:
        trial_id: Its id in the graph's messages.
        seed: Its seed.
        fitness: Its fitness, as the simulator computed it.
        characterisation: (C,) its task-specific characterisation.
        length: Steps it took.
        sdbc: (D,) its raw SDBC vector, built from the task state topic.
        behaviours: Its vector of every other characterisation asked for, by key,
            built from the task state topic too.
        characterisation_names: The names of the task-specific
            characterisation's dimensions, as the simulator gave them (it may
            give none).
    """

    trial_id: int
    seed: int
    fitness: float
    characterisation: np.ndarray
    length: int
    sdbc: np.ndarray
    behaviours: dict[str, np.ndarray] = field(default_factory=dict)
    characterisation_names: tuple[str, ...] = ()


class _TrialStream:
    """The task state messages of one trial, characterised as they arrive (the
    paper's SDBC, and any other characterisation a task state stream carries)."""

    def __init__(
        self,
        extractor: MessageSdbcExtractor,
        others: dict[str, MessageSdbcExtractor] | None = None,
    ) -> None:
        self.extractor = extractor
        self.others = dict(others or {})
        self.vector: np.ndarray | None = None
        self.vectors: dict[str, np.ndarray] = {}
        self.steps = 0
        self.error: str | None = None
        self.done = threading.Event()

    def add(self, msg: Any) -> None:
        if self.error is not None or self.done.is_set():
            return
        if msg.step != self.steps + 1:
            self.error = f"step {msg.step} arrived after step {self.steps}"
            self.done.set()
            return
        self.steps = msg.step
        try:
            vector = self.extractor.add(msg)
            others = {key: e.add(msg) for key, e in self.others.items()}
        except ValueError as error:
            self.error = str(error)
            self.done.set()
            return
        if vector is not None:
            self.vector = vector
            self.vectors = {k: v for k, v in others.items() if v is not None}
            self.done.set()


class GraphClient:
    """Drives the live graph of ``task`` from ``node``.

    Args:
        node: The caller's node, spun by an executor in another thread.
        task: The task the graph runs (its description builds the SDBC), or None
            for a task of another system, learnt from the messages.
        task_name: Its name (the simulator's ``task`` parameter).
        task_config: Its setting overrides.
        timeout: Seconds to wait for any one answer of the graph.
        stop: When set, waiting stops with :class:`Stopped`.
        n_robots: The number of robots (controllers); needed when ``task`` is
            None, and must agree with the task otherwise.
        physics: The physics model the simulator must run (its
            ``physics_model`` parameter, checked by :meth:`check_task` when the
            simulator declares it); None: not checked.
        namespace: The graph's namespace, relative to the node's (or absolute
            with a leading ``/``); "" for the node's own.

    Raises:
        ValueError: ``n_robots`` missing or not positive, or at odds with ``task``.
    """

    def __init__(
        self,
        node: Node,
        task: Task | None,
        task_name: str,
        task_config: dict[str, Any] | None = None,
        timeout: float = 30.0,
        stop: threading.Event | None = None,
        n_robots: int | None = None,
        physics: str | None = None,
        namespace: str = "",
    ) -> None:
        if task is not None:
            if n_robots not in (None, task.layout.n_controlled):
                raise ValueError(
                    f"graph client: task {task_name!r} has "
                    f"{task.layout.n_controlled} robots, not {n_robots}"
                )
            n_robots = task.layout.n_controlled
        if n_robots is None or n_robots < 1:
            raise ValueError(
                f"graph client: task {task_name!r} is not one of this project's; "
                f"the number of robots must be given (got {n_robots})"
            )
        self.node = node
        self.task = task
        self.task_name = task_name
        self.task_config = dict(task_config or {})
        self.physics = physics
        self.n_robots = n_robots
        self.namespace = namespace
        prefix = namespace.rstrip("/") + "/" if namespace.strip("/") else ""
        self.description: TaskDescription | None = (
            None if task is None else task.description
        )
        """The task description; learnt from the first trial without a task (once
        every group has shown an entity, so that its geometry is known)."""
        self._names: tuple[str, ...] | None = None
        self.timeout = timeout
        self.stop = stop or threading.Event()
        self.lock = threading.RLock()
        """Held while a genome is set and its trials run: one user at a time."""
        group = ReentrantCallbackGroup()
        self._run_trial = node.create_client(
            RunTrial, prefix + RUN_TRIAL_SERVICE, callback_group=group
        )
        self._simulator_parameters = node.create_client(
            GetParameters,
            f"{prefix}{SIMULATOR_NODE}/get_parameters",
            callback_group=group,
        )
        self._controller_parameters = [
            node.create_client(
                SetParameters,
                f"{prefix}{robot_namespace(i)}/{CONTROLLER_NODE}/set_parameters",
                callback_group=group,
            )
            for i in range(self.n_robots)
        ]
        self._task_state = node.create_subscription(
            TaskStateMsg,
            prefix + TASK_STATE_TOPIC,
            self._on_task_state,
            TASK_STATE_QOS,
            # One message at a time, in order, whatever the executor's threads.
            callback_group=MutuallyExclusiveCallbackGroup(),
        )
        self._streams: dict[int, _TrialStream] = {}
        self._streams_lock = threading.Lock()
        self._next_trial_id = time.time_ns()

    @property
    def sdbc_names(self) -> tuple[str, ...]:
        """Names of the SDBC dimensions.

        Raises:
            GraphClientError: For a task learnt from messages, before a trial ran.
        """
        if self.description is not None:
            return dimension_names(self.description)
        if self._names is None:
            raise GraphClientError(
                f"task {self.task_name!r}: no trial has run yet, so its description "
                "(and the SDBC's names) is not known"
            )
        return self._names

    def _wait_event(self, event: threading.Event, what: str, timeout: float) -> None:
        """Waits for ``event``; Stopped if :attr:`stop` is set meanwhile,
        GraphClientError naming ``what`` after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not event.wait(min(POLL, max(0.0, deadline - time.monotonic()))):
            if self.stop.is_set():
                raise Stopped(f"stopped while waiting for {what}")
            if time.monotonic() >= deadline:
                raise GraphClientError(f"no {what} within {timeout:g} s")

    def _wait_future(self, future: Any, what: str) -> Any:
        """The result of an rclpy future, waited for as :meth:`_wait_event` does."""
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if future.done():
            done.set()
        self._wait_event(done, what, self.timeout)
        return future.result()

    def _call(self, client: Any, request: Any, what: str) -> Any:
        return self._wait_future(client.call_async(request), what)

    def wait_for_graph(self, timeout: float | None = None) -> None:
        """Waits until the simulator, every controller and the task state topic
        are there, and checks that one simulator alone answers and that it runs
        this client's task.

        Raises:
            GraphClientError: Naming what is missing after ``timeout`` seconds,
                a second simulator, or the task mismatch.
        """
        timeout = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + timeout

        def missing() -> list[str]:
            names = []
            if not self._run_trial.service_is_ready():
                names.append(f"the simulator's {self._run_trial.srv_name} service")
            for i, client in enumerate(self._controller_parameters):
                if not client.service_is_ready():
                    names.append(f"robot {i}'s controller ({client.srv_name})")
            if self._task_state.get_publisher_count() == 0:
                names.append(f"a publisher of {self._task_state.topic_name}")
            return names

        while gaps := missing():
            if self.stop.is_set():
                raise Stopped("stopped while waiting for the graph")
            if time.monotonic() > deadline:
                raise GraphClientError(
                    f"the live graph is incomplete after {timeout:g} s: no "
                    + "; no ".join(gaps)
                )
            time.sleep(POLL)
        time.sleep(DISCOVERY_GRACE)
        self.check_single_simulator()
        self.check_task()

    def check_single_simulator(self) -> None:
        """Raises GraphClientError if more than one node offers the simulator's
        service: another graph in the domain, whose answers would be taken for
        this one's."""
        servers = self.node.count_services(self._run_trial.srv_name)
        if servers > 1:
            raise GraphClientError(
                f"{servers} simulators offer {self._run_trial.srv_name}: another "
                "graph runs in this DDS domain; give each graph a namespace of its "
                "own (sdbc-graph --namespace) or a ROS_DOMAIN_ID of its own"
            )

    def check_task(self) -> None:
        """Raises GraphClientError unless the simulator runs this client's task
        with the same settings, and the client's physics model if it has one and
        the simulator has a ``physics_model`` parameter (another system's
        simulator need not)."""
        if not self._simulator_parameters.wait_for_service(self.timeout):
            raise GraphClientError(
                f"no simulator parameter service within {self.timeout:g} s"
            )
        answer = self._call(
            self._simulator_parameters,
            GetParameters.Request(names=["task", "task_config"]),
            "answer from the simulator's parameter service",
        )
        if len(answer.values) != 2 or any(
            v.type != ParameterType.PARAMETER_STRING for v in answer.values
        ):
            raise GraphClientError(
                f"the simulator ({self._simulator_parameters.srv_name}) has no string "
                "parameters task and task_config, which the contract asks for"
            )
        name, config = (v.string_value for v in answer.values)
        try:
            same_config = parse_task_config(config) == self.task_config
        except ValueError:
            same_config = False
        if name != self.task_name or not same_config:
            raise GraphClientError(
                f"the simulator ({self._simulator_parameters.srv_name}) runs task "
                f"{name!r} with settings {config}, this client expects "
                f"{self.task_name!r} with {self.task_config}"
            )
        if self.physics is None:
            return
        # Asked alone: a simulator without the parameter answers no values at all.
        answer = self._call(
            self._simulator_parameters,
            GetParameters.Request(names=[PHYSICS_MODEL_PARAMETER]),
            "answer from the simulator's parameter service",
        )
        values = [v for v in answer.values if v.type == ParameterType.PARAMETER_STRING]
        if values and values[0].string_value != self.physics:
            raise GraphClientError(
                f"the simulator runs the {values[0].string_value!r} physics model "
                f"(its {PHYSICS_MODEL_PARAMETER} parameter), this client expects "
                f"{self.physics!r}"
            )

    def set_genome(self, genome: np.ndarray) -> None:
        """Sets ``genome`` on every robot's controller (homogeneous team).

        Raises:
            GenomeRejected: Naming the robot and the controller's reason.
            GraphClientError: A controller did not answer.
        """
        parameter = Parameter(
            "genome", Parameter.Type.DOUBLE_ARRAY, np.asarray(genome, float).tolist()
        ).to_parameter_msg()
        futures = [
            client.call_async(SetParameters.Request(parameters=[parameter]))
            for client in self._controller_parameters
        ]
        for i, future in enumerate(futures):
            answer = self._wait_future(future, f"answer from robot {i}'s controller")
            result = answer.results[0]
            if not result.successful:
                raise GenomeRejected(i, result.reason)

    def _on_task_state(self, msg: TaskStateMsg) -> None:
        with self._streams_lock:
            stream = self._streams.get(msg.trial_id)
        if stream is not None:
            stream.add(msg)

    def run_trial(
        self, seed: int, characterisations: tuple[CharacterisationSpec, ...] = ()
    ) -> LiveTrial:
        """Runs one trial with the controllers' current genome.

        Args:
            seed: The trial's seed.
            characterisations: Characterisations to make besides the task's and
                the paper's SDBC; each must be one a task state stream carries
                (:func:`check_live_characterisations`).

        Raises:
            TrialFailed: The simulator aborted it (its message says why), or its
                task state stream was incomplete in every attempt.
            ValueError: A characterisation needs what the graph does not publish.
        """
        others = check_live_characterisations(characterisations)
        problem = ""
        for attempt in range(1, TRIAL_ATTEMPTS + 1):
            trial_id = self._next_trial_id
            self._next_trial_id += 1
            stream = _TrialStream(
                MessageSdbcExtractor(self.description),
                {
                    spec.key: MessageSdbcExtractor(
                        self.description,
                        make_extractor=partial(
                            OptionedSdbcExtractor,
                            spec.options,
                            fixed_static_geometry=False,
                        ),
                    )
                    for spec in others
                },
            )
            with self._streams_lock:
                self._streams[trial_id] = stream
            try:
                answer = self._call(
                    self._run_trial,
                    RunTrial.Request(task=self.task_name, seed=seed, trial_id=trial_id),
                    f"answer from the simulator for trial seed {seed}",
                )
                if not answer.success:
                    raise TrialFailed(answer.message)
                self._wait_event(
                    stream.done, f"last task state of trial {trial_id}", self.timeout
                )
            finally:
                with self._streams_lock:
                    del self._streams[trial_id]
            if stream.vector is not None and stream.steps == answer.length:
                if self.description is None:
                    self._names = stream.extractor.dimension_names
                    if not stream.extractor.unknown_geometries:
                        self.description = stream.extractor.description
                return LiveTrial(
                    trial_id=trial_id,
                    seed=seed,
                    fitness=answer.fitness,
                    characterisation=np.asarray(answer.characterisation),
                    length=answer.length,
                    sdbc=stream.vector,
                    behaviours=stream.vectors,
                    characterisation_names=tuple(answer.characterisation_names),
                )
            problem = stream.error or (
                f"{stream.steps} task state messages for {answer.length} steps"
            )
            # Said, not only retried: a malformed message points at a publisher.
            self.node.get_logger().warning(
                f"trial {trial_id} (seed {seed}): bad task state stream ({problem}); "
                f"attempt {attempt} of {TRIAL_ATTEMPTS}"
            )
        raise TrialFailed(
            f"trial seed {seed}: the task state stream was incomplete in "
            f"{TRIAL_ATTEMPTS} attempts ({problem})"
        )
