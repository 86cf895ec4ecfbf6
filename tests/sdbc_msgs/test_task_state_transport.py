"""A TaskState crosses a process boundary intact, every field of every geometry kind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

PUBLISHER = Path(__file__).with_name("task_state_publisher.py")


def as_plain(value):
    """A message as nested dicts and lists, so that == compares every field."""
    if hasattr(value, "get_fields_and_field_types"):
        return {
            field: as_plain(getattr(value, field))
            for field in value.get_fields_and_field_types()
        }
    if isinstance(value, (list, tuple)) or type(value).__name__ == "array":
        return [as_plain(item) for item in value]
    return value


def test_task_state_from_another_process_arrives_intact(ros_home):
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from sdbc_msgs.msg import Entity, TaskState

    sys.path.insert(0, str(PUBLISHER.parent))
    from task_state_publisher import sample_task_state

    expected = sample_task_state()
    kinds = {e.geometry for g in expected.groups for e in g.entities}
    assert kinds == {
        Entity.GEOMETRY_CIRCLE,
        Entity.GEOMETRY_POINT,
        Entity.GEOMETRY_POLYGON,
    }

    publisher = subprocess.Popen(
        [sys.executable, str(PUBLISHER)], env=os.environ.copy()
    )
    received: list[TaskState] = []
    rclpy.init()
    node = Node("task_state_listener")
    try:
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(TaskState, "task_state", received.append, qos)
        deadline = time.monotonic() + 30.0
        while not received and time.monotonic() < deadline:
            assert publisher.poll() is None, "the publisher process died"
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        publisher.send_signal(signal.SIGINT)
        try:
            publisher.wait(timeout=10)
        except subprocess.TimeoutExpired:
            publisher.kill()

    assert received, "no TaskState received from the publisher process within 30 s"
    got = received[0]
    assert as_plain(got) == as_plain(expected)
    # Doubles travel bit for bit, not just approximately.
    assert got.groups[0].entities[1].state[1] == 1e-300
    assert got.groups[0].entities[1].state[2] == 1.0 / 3.0
    assert got.trial_id == 2**40 + 7
    assert len(got.groups[2].entities[0].segments) == 8
    assert got.groups[3].entities == []


def test_interface_definitions_are_installed_where_ros_tools_look():
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory("sdbc_msgs"))
    for name in (
        "Entity",
        "EntityGroup",
        "TaskState",
        "SensorReadings",
        "RobotCommand",
        "GenerationStats",
    ):
        definition = share / "msg" / f"{name}.msg"
        assert definition.is_file(), definition
        assert definition.read_text().strip()
    assert (share / "srv" / "RunTrial.srv").is_file()
    marker = (
        share.parent
        / "ament_index"
        / "resource_index"
        / "rosidl_interfaces"
        / "sdbc_msgs"
    )
    assert marker.is_file()
    assert "msg/TaskState.msg" in marker.read_text()
