"""The live graph's interface: node, topic and service names, QoS, and the task
parameters that every node of a graph shares.

Names are relative, so a whole graph can be pushed into a namespace with
``--ros-args -r __ns:=/team_a``. Robot i's topics live in the namespace
``robot_<i>``: the simulator publishes ``robot_<i>/sensors`` and subscribes to
``robot_<i>/command``; robot i's controller node is ``robot_<i>/controller``.

QoS, chosen on purpose:

- Lockstep topics (sensors, commands) are reliable (a lost message would stall
  the trial until the timeout) and transient-local: a reader that matches a
  writer after it wrote still gets its messages, so the first step of a trial
  cannot be lost to discovery. The lockstep's readers keep one message (at most
  one per topic is ever in flight in lockstep); the writers keep a trial of
  history, so that a recorder gets every step. Stale messages are told apart by
  trial id and step.
- The task state is reliable with a history of :data:`TASK_STATE_DEPTH` messages,
  a whole default-length trial, so that a subscriber building SDBCs never misses
  a step while it catches up; a missed step is detected downstream (the stream
  extractor demands consecutive steps), never silently averaged over.
- Characterisations (one message per trial) are reliable, transient-local and
  :data:`TASK_STATE_DEPTH` deep: no trial's vector is lost to a late or slow reader.
- Markers and statistics are for people watching: reliable, shallow.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import rclpy.utilities
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from sdbc_sim.task import Task

# The task_config parameter's text, re-exported: it lives in sdbc_sim.tasks so
# that sdbc-conformance reads task settings without ROS 2.
from sdbc_sim.tasks import format_task_config as format_task_config
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks import parse_task_config as parse_task_config

SIMULATOR_NODE = "simulator"
"""Name of the simulator node."""
CONTROLLER_NODE = "controller"
"""Name of a controller node, inside its robot's namespace."""
EVOLUTION_NODE = "evolution"
"""Name of the evolution node."""
RECORDER_NODE = "recorder"
"""Name of the recorder node."""
CHARACTERISER_NODE = "characteriser"
"""Name of the characteriser node."""

SENSORS_TOPIC = "sensors"
"""sdbc_msgs/SensorReadings, one robot's inputs, inside the robot's namespace."""
COMMAND_TOPIC = "command"
"""sdbc_msgs/RobotCommand, one robot's outputs, inside the robot's namespace."""
TASK_STATE_TOPIC = "task_state"
"""sdbc_msgs/TaskState of the running trial, every step."""
MARKERS_TOPIC = "markers"
"""visualization_msgs/MarkerArray of the running trial, for RViz or Foxglove."""
RUN_TRIAL_SERVICE = "run_trial"
"""sdbc_msgs/srv/RunTrial, offered by the simulator."""
GENERATION_STATS_TOPIC = "generation_stats"
"""sdbc_msgs/GenerationStats, one message per generation."""
BEST_GENOME_TOPIC = "best_genome"
"""std_msgs/Float64MultiArray, the best genome of the latest generation."""
CHARACTERISATION_TOPIC = "characterisation"
"""sdbc_msgs/Characterisation, one message per trial, from the characteriser."""
RECORDER_READY_TOPIC = "recorder/ready"
"""std_msgs/Bool, latched: true once the recorder has matched every publisher of
every topic it records."""
REPLAY_BEST_SERVICE = "replay_best"
"""std_srvs/Trigger, offered by the evolution node: run the current best live."""

TASK_STATE_DEPTH = 1000
"""History of the task state topic: the longest default trial (gate escape)."""

LOCKSTEP_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Sensors and commands as the lockstep reads them: reliable, transient-local, one
message deep (a reader only ever wants the latest)."""
LOCKSTEP_PUBLISHER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=TASK_STATE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Sensors and commands as they are published: a trial of history, so that a
reader that records them (and missed some, or matched late) gets every step
resent; the lockstep's own readers still keep only the latest."""
TASK_STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=TASK_STATE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Task state: reliable, a trial deep."""
DISPLAY_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Markers and generation statistics: reliable, shallow."""
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""The best genome: the latest value, also for subscribers that join later."""
CHARACTERISATION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=TASK_STATE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Characterisations: reliable, transient-local and deep, so that a subscriber that
joins late or falls behind still gets every trial's vector."""


def robot_namespace(robot: int) -> str:
    """``robot_<i>``: the namespace of robot ``robot``'s topics and controller."""
    if robot < 0:
        raise ValueError(f"robot index must be non-negative, got {robot}")
    return f"robot_{robot}"


def robot_topic(robot: int, topic: str) -> str:
    """``robot_<i>/<topic>``, relative to the simulator's namespace."""
    return f"{robot_namespace(robot)}/{topic}"


def build_task(name: str, task_config: str) -> Task:
    """The task that the ``task`` and ``task_config`` parameters name.

    Raises:
        ValueError: Unknown task, malformed ``task_config``, unknown setting or
            bad value, each named.
    """
    return make_task(name, **parse_task_config(task_config))


class UsageError(ValueError):
    """A node's command line that cannot be used; the message says why."""


def split_ros_arguments(
    prog: str, argv: Sequence[str] | None = None, *, allow_plain: bool = False
) -> tuple[list[str], list[str]]:
    """Splits a node's command line into what ``rclpy.init`` takes and the rest.

    Args:
        prog: The node's program name, for messages.
        argv: The command line, program name first; ``sys.argv`` if None.
        allow_plain: Whether the node takes arguments of its own (outside
            ``--ros-args``); if not, any such argument is an error.

    Returns:
        (the whole command line for ``rclpy.init``, the node's own arguments).

    Raises:
        UsageError: On malformed ROS arguments, or unexpected plain ones.
    """
    full = list(sys.argv if argv is None else argv)
    try:
        plain = rclpy.utilities.remove_ros_args(full)[1:]
    except RuntimeError as error:  # rclpy's RCLInvalidROSArgsError
        raise UsageError(f"{prog}: error: {error}") from error
    if plain and not allow_plain:
        raise UsageError(
            f"{prog}: error: unknown arguments {plain}; ROS arguments go after "
            "--ros-args"
        )
    return full, plain
