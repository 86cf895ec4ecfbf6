"""``controller_node``: one robot's neural controller in the live graph.

The node ``robot_<i>/controller`` holds its genome as the double-array parameter
``genome``, reads the robot's inputs on ``robot_<i>/sensors`` and answers every
reading at once with the network's outputs on ``robot_<i>/command``, copying the
reading's trial id, step and robot index (the simulator's lockstep matches on them).
The outputs are those of :func:`sdbc_sim.network.forward`, the engine's own
network arithmetic, so a robot computes here exactly what it computes in a batch.

A command is stamped with the wall time of its answer or, with ``use_sim_time``,
with its readings' stamp (the simulated time of the step it answers).

A genome is checked when it is set, at start-up (``-p`` or ``--params-file``) or
later (``ros2 param set``, the evolution node): it must have the task network's
number of weights, W = (I + 1) H + (H + 1) O, all finite. A bad one is rejected with
a reason naming the problem and the node keeps its previous genome; at start-up
the node exits instead, before any work runs. Until a genome is set the node does
not answer, and the simulator's timeout names the robot.

Usage::

    controller_node --ros-args -r __ns:=/robot_2 -p task:=gate_escape \\
        --params-file genome.yaml
    controller_node --robots 0 1 2 3 --ros-args --params-file graph_params.yaml

With ``--robots`` several controllers (one node per robot, each in its robot's
namespace) share one process and one executor; a pushed namespace
(``-r __ns:=/g1``, or a launch file's ``namespace``) goes above each robot's:
``/g1/robot_2/controller``. Without ``--robots`` the node is robot 0's,
``robot_0/controller``, unless ``__ns`` names its namespace whole, as in the
first example.

Ctrl-C and SIGTERM stop the node once its answers in flight have been
acknowledged by their readers (at most a few seconds), so that a recorder gets
the last step's commands too.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
)
from rclpy.executors import (
    Executor,
)
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.parameter import Parameter

from sdbc_msgs.msg import RobotCommand, SensorReadings
from sdbc_sim.network import NetworkShape, forward
from sdbc_sim.nodes.interface import (
    COMMAND_TOPIC,
    CONTROLLER_NODE,
    LOCKSTEP_PUBLISHER_QOS,
    LOCKSTEP_QOS,
    SENSORS_TOPIC,
    build_task,
    pushed_namespace,
    robot_namespace,
)
from sdbc_sim.nodes.parameters import CheckedNode
from sdbc_sim.nodes.shutdown import StopSignals
from sdbc_sim.nodes.startup import NodeProgram, Startup, run_node_program

DEFAULT_TASK = "gate_escape"
"""Task of a node started without a ``task`` parameter."""
IDLE_PERIOD = 0.1
"""Seconds after which an idle controller lets the executor look for work."""


def genome_problem(values: Sequence[float], shape: NetworkShape) -> str | None:
    """Why ``values`` cannot be a genome of a network of ``shape``, or None.

    The reason names the problem: the length against the network's
    W = (I + 1) H + (H + 1) O weights, or the first non-finite values.
    """
    genome = np.asarray(values, dtype=np.float64)
    if genome.ndim != 1 or genome.shape[0] != shape.genome_length:
        return (
            f"genome has {genome.size} values; the {shape.n_inputs}-"
            f"{shape.n_hidden}-{shape.n_outputs} network needs "
            f"{shape.genome_length} = ({shape.n_inputs} + 1) x {shape.n_hidden} + "
            f"({shape.n_hidden} + 1) x {shape.n_outputs}"
        )
    bad = np.flatnonzero(~np.isfinite(genome))
    if bad.size:
        shown = ", ".join(f"[{i}] = {genome[i]}" for i in bad[:5])
        more = f" and {bad.size - 5} more" if bad.size > 5 else ""
        return f"genome has non-finite values: {shown}{more}"
    return None


class ControllerNode(CheckedNode):
    """The controller of one robot.

    Parameters (ROS):
        task: Task name (read-only); fixes the network's layer sizes.
        task_config: YAML mapping of task setting overrides (read-only).
        genome: The network's weights (double array), checked when set.

    Args:
        robot: Index of the robot, used for its namespace ``robot_<i>``.
        namespace: The namespace above the robot's (``/g1`` gives
            ``/g1/robot_<i>``), kept whatever ``__ns`` remapping the command line
            has; None: ``robot_<i>``, which such a remapping replaces.
        **kwargs: Passed on to :class:`rclpy.node.Node`.

    Raises:
        ValueError: A bad task, task_config or start-up genome, naming it.
    """

    def __init__(
        self, robot: int = 0, namespace: str | None = None, **kwargs: Any
    ) -> None:
        if namespace is None:
            super().__init__(
                CONTROLLER_NODE, namespace=robot_namespace(robot), **kwargs
            )
        else:
            # A node's own arguments come before the process's in rcl's
            # remapping, so this rule wins over the pushed ``__ns``.
            own = f"{namespace.rstrip('/')}/{robot_namespace(robot)}"
            super().__init__(
                CONTROLLER_NODE,
                namespace=own,
                cli_args=["--ros-args", "-r", f"__ns:={own}"],
                **kwargs,
            )
        task_name = self.declare_parameter(
            "task",
            DEFAULT_TASK,
            ParameterDescriptor(
                description="Task name; fixes the network's layer sizes",
                read_only=True,
            ),
        ).value
        task_config = self.declare_parameter(
            "task_config",
            "{}",
            ParameterDescriptor(
                description="YAML mapping of task setting overrides",
                read_only=True,
            ),
        ).value
        self.shape = build_task(task_name, task_config).network
        self._genome: np.ndarray | None = None
        self._silent_warned = False
        self._sim_time = bool(self.get_parameter("use_sim_time").value)
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._declaring = True
        try:
            self.declare_parameter(
                "genome",
                Parameter.Type.DOUBLE_ARRAY,
                ParameterDescriptor(
                    type=ParameterType.PARAMETER_DOUBLE_ARRAY,
                    description=(
                        f"Network weights: {self.shape.genome_length} finite values "
                        "(hidden units' input weights and bias, then output units')"
                    ),
                ),
            )
        except (InvalidParameterTypeException, InvalidParameterValueException) as error:
            raise ValueError(f"parameter genome: {error}") from None
        finally:
            self._declaring = False
        self.publisher = self.create_publisher(
            RobotCommand, COMMAND_TOPIC, LOCKSTEP_PUBLISHER_QOS
        )
        self._command = RobotCommand()  # refilled for every answer
        self.sensors = self.create_subscription(
            SensorReadings, SENSORS_TOPIC, self.answer, LOCKSTEP_QOS
        )

    @property
    def genome(self) -> np.ndarray | None:
        """The genome in use, or None before one is set."""
        value = self.get_parameter_or("genome", None)
        if value is None or value.type_ != Parameter.Type.DOUBLE_ARRAY:
            return None
        return np.asarray(value.value, dtype=np.float64)

    def _check_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name != "genome":
                continue
            if parameter.type_ == Parameter.Type.NOT_SET and self._declaring:
                continue  # declared without a value: no genome yet
            if parameter.type_ != Parameter.Type.DOUBLE_ARRAY:
                return SetParametersResult(
                    successful=False,
                    reason=f"genome must be a double array, got {parameter.type_.name}",
                )
            problem = genome_problem(parameter.value, self.shape)
            if problem is not None:
                self.get_logger().warning(f"genome rejected: {problem}")
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == "use_sim_time":
                self._sim_time = bool(parameter.value)
            if parameter.name == "genome" and parameter.type_ != Parameter.Type.NOT_SET:
                self._genome = np.asarray(parameter.value, dtype=np.float64)
                self._silent_warned = False
                self.get_logger().debug(f"genome set ({self._genome.size} weights)")

    def answer(self, readings: SensorReadings) -> None:
        """Publishes the command for ``readings`` (none without a genome)."""
        if self._genome is None:
            if not self._silent_warned:
                self.get_logger().warning(
                    "sensor readings arrived but no genome is set: not answering"
                )
                self._silent_warned = True
            return
        x = np.frombuffer(readings.values, dtype=np.float64)
        if x.shape[0] != self.shape.n_inputs:
            self.get_logger().error(
                f"trial {readings.trial_id} step {readings.step}: "
                f"{x.shape[0]} sensor values, the network takes "
                f"{self.shape.n_inputs}: not answering"
            )
            return
        outputs = forward(self._genome, self.shape, x.reshape(1, -1))[0]
        command = self._command
        command.outputs = outputs.tolist()
        command.trial_id = readings.trial_id
        command.step = readings.step
        command.robot = readings.robot
        if self._sim_time:
            # The simulated instant of the readings: simulated time stands still
            # while the simulator waits for the commands.
            command.header.stamp = readings.header.stamp
        else:
            command.header.stamp.sec, command.header.stamp.nanosec = divmod(
                time.time_ns(), 1_000_000_000
            )
        self.publisher.publish(command)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="controller_node",
        description=(
            "Neural controller(s) of robots in the live sdbc graph. ROS arguments "
            "follow --ros-args (e.g. -p task:=gate_escape --params-file F)."
        ),
    )
    parser.add_argument(
        "--robots",
        type=int,
        nargs="+",
        metavar="I",
        help=(
            "robot indices served by this process, one node each in robot_<i> "
            "under any pushed namespace (default: robot 0, in robot_0 or the "
            "namespace that __ns names)"
        ),
    )
    return parser


def _make_nodes(startup: Startup) -> Iterator[ControllerNode]:
    robots = startup.args.robots
    if robots is None:
        yield ControllerNode(0)
        return
    if len(set(robots)) != len(robots) or min(robots) < 0:
        raise ValueError(
            f"--robots must be distinct non-negative indices, got {robots}"
        )
    pushed = pushed_namespace(startup.ros_args, CONTROLLER_NODE)
    for robot in robots:
        yield ControllerNode(robot, namespace=pushed)


def _serve(startup: Startup, nodes: Sequence[ControllerNode]) -> int:
    serve(nodes, startup.executor, startup.stop)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    # Ctrl-C ends serve() but keeps the context up, so that the last commands
    # can still reach slower readers (a recorder) before the nodes go.
    return run_node_program(
        NodeProgram(
            name="controller_node",
            make_nodes=_make_nodes,
            serve=_serve,
            parser=build_parser(),
            flush=lambda node: [node.publisher],
        ),
        argv,
    )


def serve(
    nodes: Sequence[ControllerNode], executor: Executor, stop: StopSignals
) -> None:
    """Answers sensor readings until ``stop`` is requested.

    Readings are taken straight from an rcl wait set and answered at once: an
    executor round in Python costs more than the network itself, and lockstep
    waits for the slowest robot. Everything else the nodes serve (their parameter
    services, QoS events) goes through ``executor`` as usual, whenever the wait
    set sees a service request, and at least every :data:`IDLE_PERIOD` seconds.
    """
    context = executor.context
    interrupt = stop.guard
    services = [service for node in nodes for service in node.services]
    wait_set = _rclpy.WaitSet(len(nodes), 1, 0, 0, len(services), 0, context.handle)
    while context.ok() and not stop.requested.is_set():
        wait_set.clear_entities()
        for node in nodes:
            wait_set.add_subscription(node.sensors.handle)
        for service in services:
            wait_set.add_service(service.handle)
        wait_set.add_guard_condition(interrupt.handle)
        wait_set.wait(int(IDLE_PERIOD * 1e9))
        ready = wait_set.get_ready_entities("subscription")
        for node in nodes:
            if node.sensors.handle.pointer in ready:
                while (
                    taken := node.sensors.handle.take_message(SensorReadings, False)
                ) is not None:
                    node.answer(taken[0])
        if wait_set.get_ready_entities("service") or not ready:
            executor.spin_once(timeout_sec=0.0)


if __name__ == "__main__":
    sys.exit(main())
