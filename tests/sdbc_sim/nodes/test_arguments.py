"""Command lines of the nodes: ROS arguments for rclpy, the rest for the node."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.ros


def test_ros_arguments_go_to_rclpy_and_the_rest_to_the_node():
    from sdbc_sim.nodes.interface import split_ros_arguments

    argv = ["controller_node", "--robots", "0", "1", "--ros-args", "-p", "task:=x"]
    full, plain = split_ros_arguments("controller_node", argv, allow_plain=True)
    assert full == argv
    assert plain == ["--robots", "0", "1"]


def test_a_node_without_arguments_of_its_own_names_the_stray_ones():
    from sdbc_sim.nodes.interface import UsageError, split_ros_arguments

    with pytest.raises(
        UsageError, match=r"simulator_node: .*\['--task', 'x'\].*--ros-args"
    ):
        split_ros_arguments("simulator_node", ["simulator_node", "--task", "x"])
    full, plain = split_ros_arguments(
        "simulator_node", ["simulator_node", "--ros-args", "-p", "task:=x"]
    )
    assert plain == []


def test_malformed_ros_arguments_are_a_usage_error():
    from sdbc_sim.nodes.interface import UsageError, split_ros_arguments

    with pytest.raises(UsageError, match="simulator_node: error"):
        split_ros_arguments("simulator_node", ["simulator_node", "--ros-args", "-p"])
