"""The live graph's interface: node, topic and service names, QoS, and the task
parameters that every node of a graph shares.

Names are relative, so a whole graph can be pushed into a namespace with
``--ros-args -r __ns:=/team_a``. Robot i's topics live in the namespace
``robot_<i>``: the simulator publishes ``robot_<i>/sensors`` and subscribes to
``robot_<i>/command``; robot i's controller node is ``robot_<i>/controller``. A
process serving several robots (``controller_node --robots 0 1 2 3``) keeps each
robot's namespace under the pushed one (``/team_a/robot_2/controller``): rcl's
``__ns`` remapping would otherwise replace every node's namespace by the same one
(:func:`pushed_namespace`).

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
- ``/clock`` and the poses are reliable and a trial deep, like the task state, so
  that a recorder gets every step's tick and pose.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any

import rclpy.utilities
import yaml
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from sdbc_sim.task import Task
from sdbc_sim.tasks import make_task

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
POSES_TOPIC = "poses"
"""geometry_msgs/PoseArray of the running trial's bodies, every step: position and
heading of each, the controlled robots first (pose i is robot i's)."""
CLOCK_TOPIC = "/clock"
"""rosgraph_msgs/Clock, the simulated time, published by the simulator. Absolute,
as every ROS 2 node with ``use_sim_time`` reads it: two graphs with simulated time
in one domain remap it (``-r /clock:=/team_a/clock`` on every node of a graph)."""
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
CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=TASK_STATE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""The simulated clock: reliable and a trial deep, so that a recorder gets every
step's tick; rclpy's own ``use_sim_time`` subscription (best effort, one deep)
matches it."""
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


def parse_task_config(text: str) -> dict[str, Any]:
    """The task setting overrides held by a ``task_config`` parameter.

    Args:
        text: A YAML (or JSON) mapping of task settings, e.g. ``{max_steps: 300}``;
            empty means the task's defaults.

    Raises:
        ValueError: If the text is not YAML or not a mapping with string keys.
    """
    try:
        data = yaml.safe_load(text) if text.strip() else {}
    except yaml.YAMLError as error:
        raise ValueError(f"task_config: not valid YAML ({error})") from None
    if data is None:
        return {}
    if not isinstance(data, Mapping) or not all(isinstance(k, str) for k in data):
        raise ValueError(
            f"task_config: expected a mapping of task settings such as "
            f"'{{max_steps: 300}}', got {text!r}"
        )
    return dict(data)


def format_task_config(overrides: Mapping[str, Any]) -> str:
    """The ``task_config`` parameter text for ``overrides`` (inverse of
    :func:`parse_task_config`)."""
    return yaml.safe_dump(dict(overrides), default_flow_style=True).strip()


def build_task(name: str, task_config: str) -> Task:
    """The task that the ``task`` and ``task_config`` parameters name.

    Raises:
        ValueError: Unknown task, malformed ``task_config``, unknown setting or
            bad value, each named.
    """
    return make_task(name, **parse_task_config(task_config))


_VALUED_ROS_FLAGS = frozenset(
    {
        "-p",
        "--param",
        "--params-file",
        "-e",
        "--enclave",
        "--log-level",
        "--log-config-file",
        "--log-file-name",
    }
)
"""rcl's flags inside ``--ros-args`` that take a value, other than ``-r``."""


def ros_flag_values(argv: Sequence[str], flags: frozenset[str]) -> list[str]:
    """The values given to ``flags`` inside the ``--ros-args`` sections of
    ``argv``, in order (rcl's grammar: a section runs from ``--ros-args`` to
    ``--`` or the end; every flag but the boolean ones takes the next word)."""
    values: list[str] = []
    inside = False
    words = iter(argv)
    for word in words:
        if not inside:
            inside = word == "--ros-args"
        elif word == "--":
            inside = False
        elif word == "--ros-args":
            continue
        elif word in flags:
            values.append(next(words, ""))
        elif word in _VALUED_ROS_FLAGS or word in ("-r", "--remap"):
            next(words, None)
    return values


def pushed_namespace(argv: Sequence[str], node_name: str) -> str:
    """The namespace that the command line's ``__ns`` remapping gives a node named
    ``node_name``, or ``""`` without one.

    rcl applies the first rule that matches, ``__ns:=NS`` or ``NAME:__ns:=NS``
    for the node's name; a launch file's ``namespace`` arrives as the former.
    """
    for rule in ros_flag_values(argv, frozenset({"-r", "--remap"})):
        target, _, namespace = rule.partition(":=")
        node, _, key = target.rpartition(":")
        if key == "__ns" and node in ("", node_name):
            namespace = namespace.rstrip("/")
            return (
                namespace
                if not namespace or namespace.startswith("/")
                else ("/" + namespace)
            )
    return ""


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
