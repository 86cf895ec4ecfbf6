"""Publishes one hand-made TaskState repeatedly; the test runs it as a process."""

from __future__ import annotations

import sys

import rclpy
from geometry_msgs.msg import Point
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from sdbc_msgs.msg import Entity, EntityGroup, TaskState


def sample_task_state() -> TaskState:
    """A task state with a circle group, a point group and a polygon group."""
    robots = EntityGroup(
        name="Agent",
        attribute_names=["x", "y", "energy level"],
        min_size=0,
        max_size=3,
        is_static=False,
        entities=[
            Entity(
                geometry=Entity.GEOMETRY_CIRCLE,
                state=[12.5, -3.25, 499.0],
                centre=Point(x=12.5, y=-3.25),
                radius=4.0,
            ),
            Entity(
                geometry=Entity.GEOMETRY_CIRCLE,
                state=[0.1, 1e-300, 1.0 / 3.0],
                centre=Point(x=0.1, y=1e-300),
                radius=2.5,
            ),
        ],
    )
    beacons = EntityGroup(
        name="Beacon",
        attribute_names=["is lit"],
        min_size=1,
        max_size=1,
        is_static=True,
        entities=[
            Entity(
                geometry=Entity.GEOMETRY_POINT,
                state=[1.0],
                centre=Point(x=-7.0, y=99.0),
            )
        ],
    )
    wall_points = [(0.0, 87.5), (0.0, 200.0), (200.0, 200.0), (200.0, 0.0), (0.0, 0.0)]
    segments = []
    for (x0, y0), (x1, y1) in zip(wall_points, wall_points[1:], strict=False):
        segments += [Point(x=x0, y=y0), Point(x=x1, y=y1)]
    walls = EntityGroup(
        name="Wall",
        attribute_names=[],
        min_size=1,
        max_size=1,
        is_static=True,
        entities=[Entity(geometry=Entity.GEOMETRY_POLYGON, segments=segments)],
    )
    empty = EntityGroup(
        name="Prey", attribute_names=["x"], min_size=0, max_size=1, is_static=False
    )
    msg = TaskState(
        task="hand_made",
        groups=[robots, beacons, walls, empty],
        trial_id=2**40 + 7,
        step=42,
    )
    msg.header.frame_id = "arena"
    msg.header.stamp.sec = 1234
    msg.header.stamp.nanosec = 5678
    msg.done = True
    return msg


def main() -> None:
    rclpy.init(args=sys.argv)
    node = Node("task_state_publisher")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    publisher = node.create_publisher(TaskState, "task_state", qos)
    message = sample_task_state()
    node.create_timer(0.1, lambda: publisher.publish(message))
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
