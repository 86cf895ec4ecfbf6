"""``recorder``: writes chosen topics of the live graph to a rosbag2 (MCAP).

The node ``recorder`` subscribes to each requested topic as soon as the topic
appears in the graph (its type read from the graph), and writes every message
as received, stamped with its time of arrival, through
:class:`sdbc_evolution.graph.bags.BagWriter`. Ctrl-C (SIGINT) or SIGTERM closes the bag
cleanly: the MCAP file is finished and ``metadata.yaml`` written.

Messages are taken straight from an rcl wait set, bytes as they arrived, without
an executor round per message: the recorder keeps up with a lockstep graph of
several thousand messages per second. Subscriptions follow their publishers'
reliability (best-effort publishers get a best-effort reader) and keep a whole
default trial of history.

Usage::

    recorder --output bags/trial_7 --topics /task_state /robot_0/sensors
    recorder --output bags/run --topics /generation_stats /best_genome \\
        --ros-args -r __ns:=/team_a

``sdbc-graph GRAPH --record BAG --trial SEED`` records one trial in one command.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerGuardCondition
from rclpy.subscription import Subscription
from sdbc_sim.nodes.interface import (
    RECORDER_NODE,
    TASK_STATE_QOS,
    UsageError,
    split_ros_arguments,
)

from sdbc_evolution.graph.bags import BagWriter, message_class

DISCOVERY_PERIOD = 0.2
"""Seconds between looks at the graph for requested topics not yet recorded."""


def _ignore(_: bytes) -> None:
    """Messages are taken by the recorder's own loop, never by an executor."""


class RecorderNode(Node):
    """Records ``topics`` into the bag at ``output``.

    Args:
        output: The bag's directory (must not exist).
        topics: Topic names; relative names resolve in the node's namespace.
        **kwargs: Passed on to :class:`rclpy.node.Node`.

    Raises:
        ValueError: No topics, or a name that is not a valid topic name.
        FileExistsError: The bag exists already.
    """

    def __init__(self, output: Path, topics: Sequence[str], **kwargs) -> None:
        super().__init__(RECORDER_NODE, start_parameter_services=False, **kwargs)
        if not topics:
            raise ValueError("recorder: no topics to record")
        try:
            self.wanted = list(
                dict.fromkeys(self.resolve_topic_name(t) for t in topics)
            )
        except Exception as error:  # rclpy raises its own validation errors
            raise ValueError(f"recorder: bad topic name: {error}") from None
        self.bag = BagWriter(output)
        self._subscriptions_by_topic: dict[str, Subscription] = {}
        self._interrupt = SignalHandlerGuardCondition(self.context)

    @property
    def missing(self) -> list[str]:
        """Requested topics not recorded yet (not seen in the graph so far)."""
        return [t for t in self.wanted if t not in self._subscriptions_by_topic]

    def discover(self) -> None:
        """Subscribes to the requested topics that have appeared in the graph."""
        missing = set(self.missing)
        if not missing:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic not in missing:
                continue
            if len(types) != 1:
                self.get_logger().error(
                    f"topic {topic} has several types {types}: not recorded"
                )
                self.wanted.remove(topic)
                continue
            msgtype = types[0]
            try:
                self.bag.add_topic(topic, msgtype)
                msg_class = message_class(msgtype)
            except (LookupError, ValueError) as error:
                self.get_logger().error(f"topic {topic}: {error}; not recorded")
                self.wanted.remove(topic)
                continue
            qos = QoSProfile(
                history=TASK_STATE_QOS.history,
                depth=TASK_STATE_QOS.depth,
                reliability=self._reliability(topic),
            )
            self._subscriptions_by_topic[topic] = self.create_subscription(
                msg_class, topic, _ignore, qos, raw=True
            )
            self.get_logger().info(f"recording {topic} ({msgtype})")

    def _reliability(self, topic: str) -> ReliabilityPolicy:
        """Reliable, unless a publisher only offers best effort."""
        offered = [
            i.qos_profile.reliability for i in self.get_publishers_info_by_topic(topic)
        ]
        if ReliabilityPolicy.BEST_EFFORT in offered:
            return ReliabilityPolicy.BEST_EFFORT
        return ReliabilityPolicy.RELIABLE

    def record(self) -> None:
        """Records until Ctrl-C or SIGTERM."""
        wait_set = None
        n_waited = -1
        next_look = 0.0
        while True:
            now = time.monotonic()
            if now >= next_look:
                self.discover()
                next_look = now + DISCOVERY_PERIOD
            subscriptions = list(self._subscriptions_by_topic.items())
            if len(subscriptions) != n_waited:
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
            if self._interrupt.handle.pointer in wait_set.get_ready_entities(
                "guard_condition"
            ) or not rclpy.ok(context=self.context):
                return

    def _take_all(self, topic: str, subscription: Subscription) -> None:
        handle = subscription.handle
        while (taken := handle.take_message(subscription.msg_type, True)) is not None:
            self.bag.write(topic, time.time_ns(), taken[0])

    def close(self) -> None:
        """Closes the bag and says what it holds (on stderr: by now Ctrl-C may
        have shut the ROS context, and its logger with it)."""
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


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    try:
        argv, plain = split_ros_arguments("recorder", argv, allow_plain=True)
    except UsageError as error:
        print(error, file=sys.stderr)
        return 2
    args = build_parser().parse_args(plain)
    rclpy.init(args=argv)
    signal.signal(signal.SIGTERM, _terminate)
    node: RecorderNode | None = None
    try:
        node = RecorderNode(args.output, args.topics)
        node.record()
    except (ValueError, FileExistsError, LookupError) as error:
        print(f"recorder: error: {error}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
