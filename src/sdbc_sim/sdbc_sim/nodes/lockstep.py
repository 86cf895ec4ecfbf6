"""Lockstep: the simulator's exchange with the robots' controllers at every step.

At step k of trial n the simulator publishes robot i's readings (trial n, step k)
on ``robot_<i>/sensors`` for every i (:meth:`Lockstep.publish`), then waits until
every robot has answered on ``robot_<i>/command`` with a command for (n, k)
(:meth:`Lockstep.gather`); only then does it step. A command for another trial or
step is stale and ignored. If some robot has not answered within the timeout, the
exchange fails with :class:`MissingCommands` naming them, so a dead controller
aborts its trial instead of hanging it.

The waiting bypasses the executor: the command subscriptions are waited on and
taken directly through an rcl wait set (as ``rclpy.wait_for_message`` does), far
cheaper than an executor round in Python per message. The subscriptions belong to
the caller's callback group; while a trial runs inside a callback of that
(mutually exclusive) group the executor leaves them alone, so nothing else takes
the commands.
"""

from __future__ import annotations

import time

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.callback_groups import CallbackGroup
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerGuardCondition

from sdbc_msgs.msg import RobotCommand, SensorReadings
from sdbc_sim.nodes.interface import (
    COMMAND_TOPIC,
    LOCKSTEP_PUBLISHER_QOS,
    LOCKSTEP_QOS,
    SENSORS_TOPIC,
    robot_topic,
)

DISCOVERY_POLL = 0.02
"""Seconds between checks while waiting for controllers to connect."""


class LockstepError(RuntimeError):
    """The exchange with the controllers failed; the message says why."""


class MissingControllers(LockstepError):
    """Some robots have no controller connected to their topics.

    Attributes:
        robots: Indices of those robots.
    """

    def __init__(self, robots: list[int], message: str) -> None:
        super().__init__(message)
        self.robots = tuple(robots)


class MissingCommands(LockstepError):
    """Some robots did not answer a step in time.

    Attributes:
        robots: Indices of the robots that did not answer.
    """

    def __init__(self, robots: list[int], message: str) -> None:
        super().__init__(message)
        self.robots = tuple(robots)


class BadCommand(LockstepError):
    """A robot answered with a command the simulator cannot use.

    Attributes:
        robot: Index of the robot.
    """

    def __init__(self, robot: int, message: str) -> None:
        super().__init__(message)
        self.robot = robot


class Interrupted(LockstepError):
    """The process is shutting down (Ctrl-C) while waiting for commands."""


def _ignore(_: RobotCommand) -> None:
    """Commands taken by the executor between trials are stale by definition."""


class Lockstep:
    """The simulator's side of lockstep for a team of ``n_robots`` robots.

    Args:
        node: The simulator node; topics are relative to its namespace.
        n_robots: N, robots driven by controllers.
        n_outputs: O, network outputs per robot.
        callback_group: A mutually exclusive group that also holds the callback
            in which trials run.
        interrupt: A guard condition triggered on shutdown (Ctrl-C); default:
            rclpy's own signal handler's.
    """

    def __init__(
        self,
        node: Node,
        n_robots: int,
        n_outputs: int,
        callback_group: CallbackGroup,
        interrupt: GuardCondition | None = None,
    ) -> None:
        self.n_robots = n_robots
        self.n_outputs = n_outputs
        self._publishers = [
            node.create_publisher(
                SensorReadings, robot_topic(i, SENSORS_TOPIC), LOCKSTEP_PUBLISHER_QOS
            )
            for i in range(n_robots)
        ]
        self._subscriptions = [
            node.create_subscription(
                RobotCommand,
                robot_topic(i, COMMAND_TOPIC),
                _ignore,
                LOCKSTEP_QOS,
                callback_group=callback_group,
            )
            for i in range(n_robots)
        ]
        self.command_topics = [s.topic_name for s in self._subscriptions]
        self.sensor_topics = [p.topic_name for p in self._publishers]
        context = node.context
        self._own_interrupt = interrupt is None
        self._interrupt = (
            SignalHandlerGuardCondition(context) if interrupt is None else interrupt
        )
        self._wait_set = _rclpy.WaitSet(n_robots, 1, 0, 0, 0, 0, context.handle)
        self._clock = node.get_clock()
        # One message per robot, refilled at every step.
        self._readings = [SensorReadings(robot=i) for i in range(n_robots)]
        self._deadline_start = time.monotonic()

    def unconnected(self) -> list[int]:
        """Robots whose sensor topic has no reader or command topic no writer."""
        return [
            i
            for i in range(self.n_robots)
            if self._publishers[i].get_subscription_count() == 0
            or self._subscriptions[i].get_publisher_count() == 0
        ]

    def wait_for_controllers(self, timeout: float) -> None:
        """Returns once every robot's topics are connected to a controller.

        Raises:
            MissingControllers: After ``timeout`` seconds, naming the robots
                still without one.
        """
        deadline = time.monotonic() + timeout
        while missing := self.unconnected():
            if time.monotonic() >= deadline:
                names = ", ".join(
                    f"robot {i} ({self.sensor_topics[i]}, {self.command_topics[i]})"
                    for i in missing
                )
                raise MissingControllers(
                    missing,
                    f"no controller connected within {timeout:g} s for {names}",
                )
            time.sleep(DISCOVERY_POLL)

    def drain(self) -> None:
        """Discards every command waiting to be taken (stale by now)."""
        for subscription in self._subscriptions:
            while subscription.handle.take_message(RobotCommand, False) is not None:
                pass

    def publish(
        self, trial_id: int, step: int, inputs: np.ndarray, stamp: Time | None = None
    ) -> None:
        """Publishes every robot's readings (N, I) for step ``step`` of trial
        ``trial_id``: the robots are to answer with their commands for that step.
        ``stamp``: the readings' (default: now, by the node's clock)."""
        if stamp is None:
            stamp = self._clock.now().to_msg()
        for i, (publisher, readings) in enumerate(
            zip(self._publishers, self._readings, strict=True)
        ):
            readings.header.stamp = stamp
            readings.values = inputs[i].tolist()
            readings.trial_id = trial_id
            readings.step = step
            publisher.publish(readings)
        self._deadline_start = time.monotonic()

    def gather(self, trial_id: int, step: int, timeout: float) -> np.ndarray:
        """Waits for every robot's command for step ``step`` of trial
        ``trial_id``, at most ``timeout`` seconds after the readings went out.

        Returns:
            (N, O) the robots' outputs.

        Raises:
            MissingCommands: Some robots did not answer within ``timeout``.
            BadCommand: A robot answered with the wrong number of outputs, values
                outside [0, 1] or NaN, or another robot's index.
            Interrupted: On Ctrl-C.
        """
        outputs = np.empty((self.n_robots, self.n_outputs))
        pending = set(range(self.n_robots))
        deadline = self._deadline_start + timeout
        wait_set = self._wait_set
        while True:
            for i in list(pending):
                if self._take(i, trial_id, step, outputs):
                    pending.discard(i)
            if not pending:
                return outputs
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                missing = sorted(pending)
                topics = ", ".join(self.command_topics[i] for i in missing)
                raise MissingCommands(
                    missing,
                    f"trial {trial_id} aborted at step {step}: no command from "
                    f"robot{'s' if len(missing) > 1 else ''} "
                    f"{', '.join(map(str, missing))} ({topics}) within {timeout:g} s",
                )
            wait_set.clear_entities()
            for i in pending:
                wait_set.add_subscription(self._subscriptions[i].handle)
            wait_set.add_guard_condition(self._interrupt.handle)
            wait_set.wait(int(remaining * 1e9))
            if self._interrupt.handle.pointer in wait_set.get_ready_entities(
                "guard_condition"
            ):
                raise Interrupted(
                    f"trial {trial_id} aborted at step {step}: shutting down"
                )

    def _take(self, robot: int, trial_id: int, step: int, outputs: np.ndarray) -> bool:
        """Takes robot ``robot``'s waiting commands; True once one is for
        (trial_id, step), its outputs then in ``outputs[robot]``."""
        handle = self._subscriptions[robot].handle
        while (taken := handle.take_message(RobotCommand, False)) is not None:
            command = taken[0]
            if command.trial_id != trial_id or command.step != step:
                continue
            values = np.frombuffer(command.outputs, dtype=np.float64)
            where = (
                f"trial {trial_id} aborted at step {step}: robot {robot}'s command "
                f"({self.command_topics[robot]})"
            )
            if command.robot != robot:
                raise BadCommand(robot, f"{where} says it is for robot {command.robot}")
            if values.shape[0] != self.n_outputs:
                raise BadCommand(
                    robot,
                    f"{where} has {values.shape[0]} outputs, the task needs "
                    f"{self.n_outputs}",
                )
            if not np.all((values >= 0.0) & (values <= 1.0)):
                raise BadCommand(
                    robot, f"{where} has outputs outside [0, 1] or NaN: {values}"
                )
            outputs[robot] = values
            return True
        return False

    @property
    def publishers(self) -> list:
        """The sensor publishers, one per robot."""
        return list(self._publishers)

    def destroy(self) -> None:
        """Releases the interrupt guard condition, if it is the lockstep's own."""
        if self._own_interrupt:
            self._interrupt.destroy()
