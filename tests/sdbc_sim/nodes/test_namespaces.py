"""Namespaces that compose: a controller process serving several robots keeps each
robot's namespace under a pushed one, and a namespaced graph runs trials."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.ros

NAMESPACE = "/g1"
TASK = "gate_escape"
TASK_CONFIG = "'{max_steps: 30}'"
GRAPH_TIMEOUT = 60.0


def node_command(module: str, *args: str) -> list[str]:
    return [sys.executable, "-m", f"sdbc_sim.nodes.{module}", *args]


def environment(ros_home) -> dict[str, str]:
    return {
        **os.environ,
        "ROS_HOME": str(ros_home),
        "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
    }


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["n"], ""),
        (["n", "--ros-args", "-r", "__ns:=/g1"], "/g1"),
        (["n", "--ros-args", "--remap", "__ns:=g1/"], "/g1"),
        (["n", "--ros-args", "-r", "controller:__ns:=/a", "-r", "__ns:=/b"], "/a"),
        (["n", "--ros-args", "-r", "simulator:__ns:=/a", "-r", "__ns:=/b"], "/b"),
        # A parameter's value is not a rule; nor is anything after "--".
        (["n", "--ros-args", "-p", "-r", "--", "-r", "__ns:=/c"], ""),
        (["n", "--ros-args", "-p", "x:=1", "--", "--ros-args", "-r", "__ns:=/d"], "/d"),
    ],
)
def test_the_pushed_namespace_is_read_as_rcl_reads_it(argv, expected):
    from sdbc_sim.nodes.interface import pushed_namespace

    assert pushed_namespace(argv, "controller") == expected


def test_several_robots_in_one_process_keep_their_namespaces_under_a_pushed_one(
    ros_home,
):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sdbc_sim.tasks import make_task

    from sdbc_msgs.srv import RunTrial

    genome = "[" + ",".join(["0.1"] * make_task(TASK).genome_length) + "]"
    ros = ["-r", f"__ns:={NAMESPACE}", "-p", f"task:={TASK}"]
    ros += ["-p", f"task_config:={TASK_CONFIG}"]
    processes = [
        subprocess.Popen(
            node_command(
                "controller_node",
                "--robots",
                "0",
                "1",
                "2",
                "3",
                "--ros-args",
                *ros,
                "-p",
                f"genome:={genome}",
            ),
            env=environment(ros_home),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        ),
        subprocess.Popen(
            node_command("simulator_node", "--ros-args", *ros),
            env=environment(ros_home),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        ),
    ]
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("test_namespaces", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    expected = {(f"{NAMESPACE}/robot_{i}", "controller") for i in range(4)}
    try:
        deadline = time.monotonic() + GRAPH_TIMEOUT
        while not expected <= {
            (ns, name) for name, ns in node.get_node_names_and_namespaces()
        }:
            assert all(p.poll() is None for p in processes), "a node ended early"
            assert time.monotonic() < deadline, node.get_node_names_and_namespaces()
            time.sleep(0.1)
        client = node.create_client(RunTrial, f"{NAMESPACE}/run_trial")
        assert client.wait_for_service(timeout_sec=GRAPH_TIMEOUT)
        future = client.call_async(RunTrial.Request(seed=3, task=TASK))
        executor.spin_until_future_complete(future, timeout_sec=GRAPH_TIMEOUT)
        answer = future.result()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        for process in processes:
            process.send_signal(2)
        outputs = [p.communicate(timeout=30)[0].decode() for p in processes]
    assert answer is not None and answer.success, (answer, outputs)
    assert answer.length == 30
    assert [p.returncode for p in processes] == [0, 0], outputs
