"""``recorder``: writes chosen topics of the live graph to a rosbag2 (MCAP).

The node ``recorder`` subscribes to each requested topic as soon as the topic
appears in the graph (its type read from the graph), and writes every message
as received, stamped with its time of arrival (wall time, as ``ros2 bag record``
does), through
:class:`sdbc_evolution.graph.bags.BagWriter`. Ctrl-C (SIGINT) or SIGTERM closes the bag
cleanly: what has arrived is taken, the MCAP file finished and ``metadata.yaml``
written.

So that a bag holds every step:

- Each subscription asks for what its publishers offer: reliable unless one offers
  only best effort, transient-local if all of them are (then a publisher that
  matches late still delivers the history it keeps), a thousand messages deep.
- The node publishes ``true`` on ``recorder/ready`` (std_msgs/Bool, latched) only
  once every requested topic is subscribed and each subscription has matched every
  publisher the graph shows for its topic; a launcher waits for that before the
  first trial.
- A launcher stops the recorder last, after the publishers, and the recorder takes
  everything still waiting before it closes the bag.

Messages are taken straight from an rcl wait set, bytes as they arrived, without
an executor round per message: the recorder keeps up with a lockstep graph of
several thousand messages per second. The node is a full ROS 2 node all the same:
an executor thread answers its parameter and type description services, while the
subscriptions belong to a callback group that executors leave alone.
The bag carries each topic's offered QoS, as ``ros2 bag record`` writes it.

With ``use_sim_time`` the bag's timeline is the trial's: a message whose first
field is a header (or a time, as ``/clock``'s) is written at that stamp, the
simulated instant it describes, every other at the node's simulated clock. Arrival
times would not do: a message can arrive before the ``/clock`` tick of its step,
and would then be written a step early. Record ``/clock`` too, for players and
plots that follow it.

Usage::

    recorder --output bags/trial_7 --topics /task_state /robot_0/sensors
    recorder --output bags/run --topics /generation_stats /best_genome \\
        --ros-args -r __ns:=/team_a

``sdbc-graph GRAPH --record BAG --trial SEED`` records one trial in one command.
"""

from __future__ import annotations

import argparse
import signal
import struct
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import rclpy
from rclpy.callback_groups import CallbackGroup
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from sdbc_sim.nodes.interface import (
    LATCHED_QOS,
    RECORDER_NODE,
    RECORDER_READY_TOPIC,
    TASK_STATE_QOS,
)
from sdbc_sim.nodes.parameters import CheckedNode
from sdbc_sim.nodes.startup import NodeProgram, Startup, run_node_program
from std_msgs.msg import Bool

from sdbc_evolution.graph.bags import BagWriter, bag_qos, message_class

DISCOVERY_PERIOD = 0.2
"""Seconds between looks at the graph for requested topics not yet recorded."""
STAMP_TYPES = ("std_msgs/Header", "builtin_interfaces/Time")
"""Types of a message's first field whose stamp (a time first: int32 seconds,
uint32 nanoseconds) is read from the serialised bytes."""
_STAMP = {0: struct.Struct(">iI"), 1: struct.Struct("<iI")}
"""The stamp after the 4-byte CDR encapsulation header, by its endianness flag."""


def message_stamp_ns(raw: bytes) -> int | None:
    """The stamp of a serialised message whose first field is a stamp (see
    :data:`STAMP_TYPES`), nanoseconds; None if the bytes are too short or of an
    unknown encapsulation."""
    layout = _STAMP.get(raw[1]) if len(raw) >= 12 else None
    if layout is None:
        return None
    sec, nanosec = layout.unpack_from(raw, 4)
    return sec * 1_000_000_000 + nanosec


def _ignore(_: bytes) -> None:
    """Messages are taken by the recorder's own loop, never by an executor."""


class OwnLoopGroup(CallbackGroup):
    """A callback group that no executor runs: its subscriptions are waited on and
    taken by the recorder's own loop, while an executor serves the node's
    services."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        """Never called: nothing of this group begins execution."""


class RecorderNode(CheckedNode):
    """Records ``topics`` into the bag at ``output``.

    Args:
        output: The bag's directory (must not exist).
        topics: Topic names; relative names resolve in the node's namespace.
        **kwargs: Passed on to :class:`rclpy.node.Node`.

    Raises:
        ValueError: No topics, or a name that is not a valid topic name.
        FileExistsError: The bag exists already.
    """

    def __init__(self, output: Path, topics: Sequence[str], **kwargs: Any) -> None:
        super().__init__(RECORDER_NODE, **kwargs)
        if not topics:
            raise ValueError("recorder: no topics to record")
        try:
            self.wanted = list(
                dict.fromkeys(self.resolve_topic_name(t) for t in topics)
            )
        except Exception as error:  # rclpy raises its own validation errors
            raise ValueError(f"recorder: bad topic name: {error}") from None
        if output.exists():
            raise FileExistsError(f"bag {output} exists already; not overwriting")
        # Written only once the program has checked the node's parameters
        # (open_bag): a refused start leaves no bag behind.
        self.output = output
        self._bag: BagWriter | None = None
        self._subscriptions_by_topic: dict[str, Subscription] = {}
        self._stamped: set[str] = set()  # topics whose messages carry a stamp first
        self.sim_time = False
        self._own_loop = OwnLoopGroup()
        self._interrupt = GuardCondition(None, None, context=self.context)
        self.stopping = False
        self._ready = self.create_publisher(Bool, RECORDER_READY_TOPIC, LATCHED_QOS)
        self.is_ready = False
        self._unmatched: list[str] = []

    def open_bag(self) -> None:
        """Creates the bag; before :meth:`record`."""
        self._bag = BagWriter(self.output)

    @property
    def bag(self) -> BagWriter:
        """The bag being written (:meth:`open_bag`)."""
        if self._bag is None:
            raise RuntimeError("the recorder's bag is not open")
        return self._bag

    @property
    def missing(self) -> list[str]:
        """Requested topics not recorded yet (not seen in the graph so far)."""
        return [t for t in self.wanted if t not in self._subscriptions_by_topic]

    def discover(self) -> None:
        """Subscribes to the requested topics that have appeared in the graph, and
        announces readiness once every one is matched to all its publishers."""
        missing = set(self.missing)
        for topic, types in self.get_topic_names_and_types() if missing else ():
            if topic not in missing:
                continue
            if len(types) != 1:
                self.get_logger().error(
                    f"topic {topic} has several types {types}: not recorded"
                )
                self.wanted.remove(topic)
                continue
            self._subscribe(topic, types[0])
        if not self.is_ready:
            self._announce_when_ready()

    def _subscribe(self, topic: str, msgtype: str) -> None:
        offered = [i.qos_profile for i in self.get_publishers_info_by_topic(topic)]
        if not offered:
            return  # a subscriber made the topic appear; wait for a publisher
        try:
            self.bag.add_topic(topic, msgtype, [bag_qos(q) for q in offered])
            msg_class = message_class(msgtype)
        except (LookupError, ValueError) as error:
            self.get_logger().error(f"topic {topic}: {error}; not recorded")
            self.wanted.remove(topic)
            return
        reliability = (
            ReliabilityPolicy.BEST_EFFORT
            if any(q.reliability == ReliabilityPolicy.BEST_EFFORT for q in offered)
            else ReliabilityPolicy.RELIABLE
        )
        durability = (
            DurabilityPolicy.TRANSIENT_LOCAL
            if all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
            else DurabilityPolicy.VOLATILE
        )
        qos = QoSProfile(
            history=TASK_STATE_QOS.history,
            depth=TASK_STATE_QOS.depth,
            reliability=reliability,
            durability=durability,
        )
        self._subscriptions_by_topic[topic] = self.create_subscription(
            msg_class, topic, _ignore, qos, raw=True, callback_group=self._own_loop
        )
        described: Any = msg_class  # a generated ROS message class
        fields = list(described.get_fields_and_field_types().values())
        if fields and fields[0] in STAMP_TYPES:
            self._stamped.add(topic)
        self.get_logger().info(f"recording {topic} ({msgtype})")

    def unmatched(self) -> list[str]:
        """Requested topics not subscribed yet, or whose subscription has not
        matched every publisher the graph shows."""
        return [
            topic
            for topic in self.wanted
            if (subscription := self._subscriptions_by_topic.get(topic)) is None
            or subscription.get_publisher_count() < self.count_publishers(topic)
        ]

    def _announce_when_ready(self) -> None:
        unmatched = self.unmatched()
        if unmatched != self._unmatched:
            self._unmatched = unmatched
            if unmatched:
                self.get_logger().info(f"waiting to match: {', '.join(unmatched)}")
        if not unmatched:
            self.is_ready = True
            self._ready.publish(Bool(data=True))
            self.get_logger().info("ready: every topic matched to its publishers")

    def request_stop(self) -> None:
        """Makes :meth:`record` take what is waiting and return; safe to call from
        a signal handler."""
        self.stopping = True
        self._interrupt.trigger()

    def record(self) -> None:
        """Records until :meth:`request_stop` (Ctrl-C, SIGTERM), then takes what is
        still waiting."""
        self.sim_time = bool(self.get_parameter("use_sim_time").value)
        wait_set = None
        n_waited = -1
        next_look = 0.0
        while True:
            now = time.monotonic()
            if now >= next_look:
                self.discover()
                next_look = now + DISCOVERY_PERIOD
            subscriptions = list(self._subscriptions_by_topic.items())
            if wait_set is None or len(subscriptions) != n_waited:
                n_waited = len(subscriptions)
                wait_set = _rclpy.WaitSet(n_waited, 1, 0, 0, 0, 0, self.context.handle)
            wait_set.clear_entities()
            for _, subscription in subscriptions:
                wait_set.add_subscription(subscription.handle)
            wait_set.add_guard_condition(self._interrupt.handle)
            wait_set.wait(int(max(0.0, next_look - time.monotonic()) * 1e9))
            ready = wait_set.get_ready_entities("subscription")
            for topic, subscription in subscriptions:
                if subscription.handle.pointer in ready:
                    self._take_all(topic, subscription)
            if self.stopping or not rclpy.ok(context=self.context):
                self.drain()
                return

    def drain(self) -> None:
        """Takes every message that has arrived and not been written yet."""
        for topic, subscription in self._subscriptions_by_topic.items():
            self._take_all(topic, subscription)

    def _take_all(self, topic: str, subscription: Subscription) -> None:
        handle = subscription.handle
        stamped = self.sim_time and topic in self._stamped
        while (taken := handle.take_message(subscription.msg_type, True)) is not None:
            raw = taken[0]
            stamp = message_stamp_ns(raw) if stamped else None
            if stamp is None:
                stamp = (
                    self.get_clock().now().nanoseconds
                    if self.sim_time
                    else time.time_ns()
                )
            self.bag.write(topic, stamp, raw)

    def close(self) -> None:
        """Closes the bag and says what it holds (on stderr: by now Ctrl-C may
        have shut the ROS context, and its logger with it)."""
        if self._bag is None:
            return  # refused before it was opened
        self.bag.close()
        counts = ", ".join(f"{t}: {n}" for t, n in self.bag.counts.items())
        print(
            f"recorder: bag {self.bag.path} closed ({counts or 'empty'})",
            file=sys.stderr,
        )
        if self.missing:
            print(
                f"recorder: never seen, not recorded: {self.missing}", file=sys.stderr
            )

    def destroy_node(self) -> None:
        self._interrupt.destroy()
        super().destroy_node()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="recorder",
        description=(
            "Record topics of the live sdbc graph to a rosbag2 (MCAP + "
            "metadata.yaml); Ctrl-C closes the bag."
        ),
    )
    parser.add_argument(
        "--output", "-o", type=Path, required=True, help="bag directory (new)"
    )
    parser.add_argument(
        "--topics", nargs="+", required=True, metavar="TOPIC", help="topics to record"
    )
    return parser


def _make_nodes(startup: Startup) -> Iterator[RecorderNode]:
    node = RecorderNode(startup.args.output, startup.args.topics)
    # Ctrl-C and SIGTERM do not interrupt the recording loop where it stands (a
    # message taken but not written would be lost): they ask it to stop.
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_, node=node: node.request_stop())
    yield node


def _record(startup: Startup, nodes: Sequence[RecorderNode]) -> int:
    # The services (parameters, type description) are answered by the executor in
    # a thread of their own; the messages by the recording loop.
    threading.Thread(target=startup.executor.spin, name="services", daemon=True).start()
    nodes[0].open_bag()
    nodes[0].record()
    return 0


def _close(nodes: Sequence[RecorderNode]) -> None:
    # The bag first: the executor may be slow to stop, the data must not be.
    for node in nodes:
        node.close()


def main(argv: Sequence[str] | None = None) -> int:
    return run_node_program(
        NodeProgram(
            name="recorder",
            make_nodes=_make_nodes,
            serve=_record,
            parser=build_parser(),
            signals="own",
            errors=(ValueError, FileExistsError, LookupError),
            close=_close,
        ),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
