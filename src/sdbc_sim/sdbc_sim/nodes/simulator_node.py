"""``simulator_node``: runs trials of a task, one at a time, in lockstep with the
robots' controller nodes.

A trial starts on a call to the ``run_trial`` service (sdbc_msgs/srv/RunTrial:
task, seed, trial id). The node draws the initial conditions from the seed with the
engine's own one-trial stepper (:class:`sdbc_sim.engine.TrialStepper`, the same code
as ``run_batch``), then, at every step k = 1, 2, ...:

1. publishes each robot's sensor readings on ``robot_<i>/sensors`` and waits for
   every robot's command for step k on ``robot_<i>/command``
   (:mod:`sdbc_sim.nodes.lockstep`); a robot silent for ``command_timeout``
   seconds aborts the trial with an error naming it;
2. steps the trial with those outputs, and publishes the readings for step k + 1;
3. advances the simulated clock by ``step_period`` seconds and publishes it
   (``/clock``, rosgraph_msgs/Clock), then the task state after step k
   (``task_state``, sdbc_msgs/TaskState), the bodies' poses (``poses``,
   geometry_msgs/PoseArray: position and heading of each body, pose i robot i's)
   and, every ``marker_period`` steps, markers (``markers``,
   visualization_msgs/MarkerArray, with an arrow per body for its heading),
   while the controllers compute step k + 1; a topic without subscribers is not
   built.

Simulated time starts at 0 when the node starts and advances only with steps:
trial after trial, it never goes back. With ``use_sim_time`` on, every message of
a step is stamped with the simulated time of that step (the readings for step k
with the time before it, what follows step k with the time after it); off (the
ROS default, as for every node), with wall time. ``/clock`` is published either
way, so that the other nodes of a graph can follow it with ``use_sim_time``.

So that every reader (a recorder, a characteriser) gets every step, the node
waits before step 1 until each of its publishers has matched every reader the
graph shows (at most ``discovery_timeout`` seconds), and on Ctrl-C it waits for
its readers to acknowledge what it published before it leaves (at most
:data:`sdbc_sim.nodes.shutdown.FLUSH_TIMEOUT` seconds in all). It does not wait
for acknowledgements after every trial: with a trial of history, Fast DDS's
writers ask for them only at their periodic heartbeat, and the wait cost 1 to
3 s per 300-step trial (measured), as long as the trial itself.

The answer carries the trial's fitness, task-specific characterisation and length,
or ``success = false`` and a message saying why the trial was aborted; the node then
serves the next trial as usual. Given the same genome on the controllers and the
same seed, a live trial equals the batched engine's to the bit (with the same
physics model, the ``physics_model`` parameter): the engine's stepping and
network code run on both sides, and doubles cross DDS unchanged.

Usage::

    simulator_node --ros-args -p task:=gate_escape -p command_timeout:=2.0
    simulator_node --ros-args -p task:=gate_escape -p physics_model:=kinematic
    simulator_node --ros-args --params-file configs/ros/gate_escape.yaml
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
)
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.publisher import Publisher
from rosgraph_msgs.msg import Clock
from visualization_msgs.msg import MarkerArray

from sdbc_msgs.msg import TaskState as TaskStateMsg
from sdbc_msgs.srv import RunTrial
from sdbc_sim.engine import EngineSettings, TrialStepper
from sdbc_sim.nodes.interface import (
    CLOCK_QOS,
    CLOCK_TOPIC,
    DISPLAY_QOS,
    MARKERS_TOPIC,
    POSES_TOPIC,
    RUN_TRIAL_SERVICE,
    SIMULATOR_NODE,
    TASK_STATE_QOS,
    TASK_STATE_TOPIC,
    build_task,
)
from sdbc_sim.nodes.lockstep import Lockstep, LockstepError
from sdbc_sim.nodes.markers import body_poses, markers_from_task_state
from sdbc_sim.nodes.parameters import CheckedNode
from sdbc_sim.nodes.startup import (
    NodeProgram,
    Startup,
    run_node_program,
    spin_until_stopped,
)
from sdbc_sim.physics import MODELS, Model, PhysicsSettings
from sdbc_sim.task_state_msgs import task_state_to_msg

DEFAULT_TASK = "gate_escape"
"""Task of a node started without a ``task`` parameter."""
DEFAULT_PHYSICS_MODEL = "rigid"
"""Physics model of a node started without a ``physics_model`` parameter."""
DEFAULT_COMMAND_TIMEOUT = 2.0
"""Seconds to wait for every robot's command at a step."""
DEFAULT_DISCOVERY_TIMEOUT = 10.0
"""Seconds to wait, at a trial's start, for every robot's controller to connect."""
DEFAULT_MARKER_PERIOD = 10
"""Markers are published every this many steps (0: never)."""
MAX_TIMEOUT = 3600.0
"""Largest timeout a parameter accepts, seconds."""
DEFAULT_STEP_PERIOD = 0.1
"""Simulated seconds per step. The tasks have no step length in seconds (the
engine's speeds are in arena units per step), so this is a convention: 10 Hz, the
control rate of small e-puck-like robots. The results do not depend on it."""
MAX_STEP_PERIOD = 3600.0
"""Largest ``step_period`` accepted, seconds."""
READER_POLL = 0.02
"""Seconds between checks while waiting for readers to match."""


def engine_settings(physics_model: str) -> EngineSettings:
    """The engine settings of the ``physics_model`` parameter.

    Raises:
        ValueError: Not one of :data:`sdbc_sim.physics.MODELS`, naming the
            parameter and the allowed values.
    """
    try:
        physics = PhysicsSettings(model=cast(Model, physics_model))
    except ValueError:
        # PhysicsSettings checks the model; the message names the parameter.
        raise ValueError(
            f"parameter physics_model: {physics_model!r} is not one of "
            f"{', '.join(MODELS)}"
        ) from None
    return EngineSettings(physics=physics)


class TrialAborted(RuntimeError):
    """A trial could not run to its end; the message says why."""


@dataclass(frozen=True)
class TrialOutcome:
    """The result of one live trial.

    Attributes:
        trial_id: The trial's id in its messages.
        fitness: The trial's fitness.
        characterisation: (C,) its task-specific characterisation, each in [0, 1].
        length: Steps it took.
    """

    trial_id: int
    fitness: float
    characterisation: np.ndarray
    length: int


class SimulatorNode(CheckedNode):
    """Runs trials of one task in lockstep with the controller nodes.

    Parameters (ROS):
        task: Task name (read-only).
        task_config: YAML mapping of task setting overrides (read-only).
        physics_model: The engine's physics model, ``rigid`` (pymunk rigid
            bodies, the default) or ``kinematic`` (the authors' robots); see
            ``sdbc_sim.physics.PhysicsSettings.model`` (read-only).
        command_timeout: Seconds to wait for every robot's command at a step.
        discovery_timeout: Seconds to wait at a trial's start for every robot's
            controller to connect.
        marker_period: Publish markers every this many steps; 0 for never.
        step_period: Simulated seconds per step (``/clock``, and the stamps with
            ``use_sim_time``).

    Args:
        interrupt: Triggered on Ctrl-C, to abort a running trial; default:
            rclpy's signal handler's.
        **kwargs: Passed on to :class:`rclpy.node.Node`.

    Raises:
        ValueError: A bad task, task_config or physics_model, naming it.
    """

    def __init__(self, interrupt: Any = None, **kwargs: Any) -> None:
        super().__init__(SIMULATOR_NODE, **kwargs)
        task_name = self.declare_parameter(
            "task",
            DEFAULT_TASK,
            ParameterDescriptor(description="Task name", read_only=True),
        ).value
        task_config = self.declare_parameter(
            "task_config",
            "{}",
            ParameterDescriptor(
                description="YAML mapping of task setting overrides", read_only=True
            ),
        ).value
        physics_model = self.declare_parameter(
            "physics_model",
            DEFAULT_PHYSICS_MODEL,
            ParameterDescriptor(
                description="Physics model: rigid (pymunk bodies) or kinematic "
                "(the authors' robots: a blocked move is refused or retried sideways)",
                read_only=True,
            ),
        ).value
        settings = engine_settings(physics_model)
        for name, default, what in (
            ("command_timeout", DEFAULT_COMMAND_TIMEOUT, "every robot's command"),
            ("discovery_timeout", DEFAULT_DISCOVERY_TIMEOUT, "every controller"),
        ):
            self.declare_parameter(
                name,
                default,
                ParameterDescriptor(
                    description=f"Seconds to wait for {what}",
                    floating_point_range=[
                        FloatingPointRange(from_value=1e-3, to_value=MAX_TIMEOUT)
                    ],
                ),
            )
        self.declare_parameter(
            "marker_period",
            DEFAULT_MARKER_PERIOD,
            ParameterDescriptor(
                description="Publish markers every this many steps (0: never)",
                integer_range=[IntegerRange(from_value=0, to_value=2**31 - 1)],
            ),
        )
        self.declare_parameter(
            "step_period",
            DEFAULT_STEP_PERIOD,
            ParameterDescriptor(
                description="Simulated seconds per step, for /clock and, with "
                "use_sim_time, the stamps",
                floating_point_range=[
                    FloatingPointRange(from_value=1e-6, to_value=MAX_STEP_PERIOD)
                ],
            ),
        )
        self.task = build_task(task_name, task_config)
        self.characterisation_names = list(self.task.characterisation_names)
        self.physics_model: str = physics_model
        self._stepper = TrialStepper(self.task, settings)
        trial_group = MutuallyExclusiveCallbackGroup()
        self.lockstep = Lockstep(
            self,
            self.task.layout.n_controlled,
            self.task.network.n_outputs,
            trial_group,
            interrupt,
        )
        self._task_state = self.create_publisher(
            TaskStateMsg, TASK_STATE_TOPIC, TASK_STATE_QOS
        )
        self._markers = self.create_publisher(MarkerArray, MARKERS_TOPIC, DISPLAY_QOS)
        self._poses = self.create_publisher(PoseArray, POSES_TOPIC, TASK_STATE_QOS)
        self._clock_publisher = self.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
        self.sim_time_ns = 0
        """The simulated time, nanoseconds: step period times the steps so far."""
        self._radii = self.task.layout.radii
        self.create_service(
            RunTrial, RUN_TRIAL_SERVICE, self._serve, callback_group=trial_group
        )
        # Automatic trial ids start from the clock, so a restarted simulator
        # never reuses the ids of commands still held by transient-local topics.
        self._next_trial_id = time.time_ns()

    def announce(self) -> None:
        """Logs what the node simulates (once its parameters are checked)."""
        self.get_logger().info(
            f"task {self.task.name}: {self.task.layout.n_controlled} robots, "
            f"{self.task.network.n_inputs} inputs, {self.task.network.n_outputs} "
            f"outputs per robot; {self.physics_model} physics; "
            f"{self._parameter('step_period'):g} s per step"
        )

    def _parameter(self, name: str) -> float:
        return self.get_parameter(name).value

    def run_trial(self, seed: int, trial_id: int = 0, task: str = "") -> TrialOutcome:
        """Runs one trial in lockstep with the controllers.

        Args:
            seed: Seed of the trial's initial conditions (non-negative).
            trial_id: Id of the trial in its messages; 0 picks a fresh one.
            task: The task the caller expects; empty for the node's own.

        Raises:
            TrialAborted: A different task was asked for, the seed is negative, a
                controller is missing or silent, or a command is malformed.
        """
        if task and task != self.task.name:
            raise TrialAborted(
                f"this simulator runs task {self.task.name!r}, not {task!r}"
            )
        if seed < 0:
            raise TrialAborted(f"seed must be non-negative, got {seed}")
        if trial_id == 0:
            trial_id = self._next_trial_id
            self._next_trial_id += 1
        lockstep, stepper = self.lockstep, self._stepper
        try:
            lockstep.wait_for_controllers(self._parameter("discovery_timeout"))
            self.wait_for_readers(self._parameter("discovery_timeout"))
            lockstep.drain()
            stepper.reset(seed)
            marker_period = int(self._parameter("marker_period"))
            timeout = self._parameter("command_timeout")
            step_ns = round(self._parameter("step_period") * 1e9)
            sim_stamps = bool(self.get_parameter("use_sim_time").value)
            self._publish_clock()
            lockstep.publish(trial_id, 1, stepper.sensors(), self._stamp(sim_stamps))
            while True:
                step = stepper.step_count + 1
                stepper.step(lockstep.gather(trial_id, step, timeout))
                self.sim_time_ns += step_ns
                self._publish_clock()
                stamp = self._stamp(sim_stamps)
                # The next readings go out first: the controllers compute while
                # this step's task state is built and published.
                if not stepper.done:
                    lockstep.publish(trial_id, step + 1, stepper.sensors(), stamp)
                self._publish_state(trial_id, step, marker_period, stamp)
                if stepper.done:
                    break
        except LockstepError as error:
            raise TrialAborted(str(error)) from None
        fitness, characterisation, length = stepper.result()
        return TrialOutcome(trial_id, fitness, characterisation, length)

    @property
    def trial_publishers(self) -> list[Publisher]:
        """Every publisher of a trial's messages (rclpy's ``publishers`` lists the
        node's own too: parameter events, rosout)."""
        return [
            self._clock_publisher,
            self._task_state,
            self._poses,
            self._markers,
            *self.lockstep.publishers,
        ]

    def _stamp(self, simulated: bool) -> Time:
        """The stamp of what is published now: the simulated time, or the wall
        time (the node's clock without ``use_sim_time``)."""
        if simulated:
            sec, nanosec = divmod(self.sim_time_ns, 1_000_000_000)
            return Time(sec=sec, nanosec=nanosec)
        return self.get_clock().now().to_msg()

    def _publish_clock(self) -> None:
        if self._clock_publisher.get_subscription_count() > 0:
            sec, nanosec = divmod(self.sim_time_ns, 1_000_000_000)
            self._clock_publisher.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))

    def wait_for_readers(self, timeout: float) -> None:
        """Waits until each publisher has matched every reader that the graph
        shows for its topic (discovery is not symmetric: a reader can see a
        writer before the writer has matched it, and would then miss the first
        steps); after ``timeout`` seconds, goes on with a warning."""
        deadline = time.monotonic() + timeout
        while unmatched := [
            p.topic_name
            for p in self.trial_publishers
            if p.get_subscription_count() < self.count_subscribers(p.topic_name)
        ]:
            if time.monotonic() >= deadline:
                self.get_logger().warning(
                    f"readers of {', '.join(unmatched)} not matched within "
                    f"{timeout:g} s; they may miss the first steps"
                )
                return
            time.sleep(READER_POLL)

    def _publish_state(
        self, trial_id: int, step: int, marker_period: int, stamp: Time
    ) -> None:
        """Publishes the task state and the poses after ``step`` and, when due,
        the markers.

        Building the messages costs more than a lockstep exchange, so it is skipped
        for a topic that nobody subscribes to: there is no one to miss them.
        """
        stepper = self._stepper
        done = stepper.done
        markers_due = bool(marker_period) and (
            step % marker_period == 0 or step == 1 or done
        )
        markers_due = markers_due and self._markers.get_subscription_count() > 0
        poses_wanted = self._poses.get_subscription_count() > 0
        if not (
            markers_due or poses_wanted or self._task_state.get_subscription_count() > 0
        ):
            return
        msg = task_state_to_msg(
            stepper.state(), self.task.description, 0, trial_id, self.task.name, done
        )
        msg.header.stamp = stamp
        self._task_state.publish(msg)
        if not (markers_due or poses_wanted):
            return
        # The headings come from the engine's bodies, not the task state: the
        # task description (and the SDBCs built on it) has no orientation.
        bodies = stepper.sim.bodies
        poses = body_poses(msg.header, bodies.position[0], bodies.angle[0])
        if poses_wanted:
            self._poses.publish(poses)
        if markers_due:
            self._markers.publish(markers_from_task_state(msg, poses, self._radii))

    def _serve(
        self, request: RunTrial.Request, response: RunTrial.Response
    ) -> RunTrial.Response:
        try:
            outcome = self.run_trial(request.seed, request.trial_id, request.task)
        except TrialAborted as error:
            self.get_logger().error(str(error))
            response.success = False
            response.message = str(error)
            return response
        response.success = True
        response.message = f"trial {outcome.trial_id}: {outcome.length} steps"
        response.fitness = outcome.fitness
        response.characterisation = outcome.characterisation.tolist()
        response.characterisation_names = self.characterisation_names
        response.length = outcome.length
        return response

    def destroy_node(self) -> None:
        self.lockstep.destroy()
        super().destroy_node()


def _serve(startup: Startup, nodes: Sequence[SimulatorNode]) -> int:
    nodes[0].announce()
    return spin_until_stopped(startup, nodes)


def main(argv: Sequence[str] | None = None) -> int:
    """The ``simulator_node`` program: serves trials until Ctrl-C; the exit status."""
    # Ctrl-C aborts a running trial and leaves spin, but keeps the context up,
    # so that what was published can still reach slower readers (a recorder).
    # Two threads: parameter and graph services stay responsive while a trial runs.
    return run_node_program(
        NodeProgram(
            name="simulator_node",
            make_nodes=lambda startup: [SimulatorNode(interrupt=startup.stop.guard)],
            serve=_serve,
            threads=2,
            flush=lambda node: node.trial_publishers,
        ),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
