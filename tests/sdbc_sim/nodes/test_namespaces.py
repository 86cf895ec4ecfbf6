"""Namespaces that compose: a controller process serving several robots keeps each
robot's namespace under a pushed one, and a namespaced graph runs trials."""

from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.ros

NAMESPACE = "/g1"
TASK = "gate_escape"
TASK_CONFIG = "'{max_steps: 30}'"
GRAPH_TIMEOUT = 60.0


CONTROLLER = "sdbc_sim.nodes.controller_node"
SIMULATOR = "sdbc_sim.nodes.simulator_node"


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
    start_node, test_node
):
    from sdbc_sim.tasks import make_task

    from sdbc_msgs.srv import RunTrial

    node, executor = test_node
    genome = "[" + ",".join(["0.1"] * make_task(TASK).genome_length) + "]"
    ros = ["-r", f"__ns:={NAMESPACE}", "-p", f"task:={TASK}"]
    ros += ["-p", f"task_config:={TASK_CONFIG}"]
    robots = ["--robots", "0", "1", "2", "3"]
    processes = [
        start_node(CONTROLLER, *robots, "--ros-args", *ros, "-p", f"genome:={genome}"),
        start_node(SIMULATOR, "--ros-args", *ros),
    ]
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
        for process in processes:
            process.send_signal(2)
        outputs = [p.communicate(timeout=30)[0] for p in processes]
    assert answer is not None and answer.success, (answer, outputs)
    assert answer.length == 30
    assert [p.returncode for p in processes] == [0, 0], outputs
