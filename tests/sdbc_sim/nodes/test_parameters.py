"""Parameters a node does not declare are refused: at start-up by each of the five
node programs (one line, exit 2), at run time with a reason; a graph file's
shared keys reach a node only as far as it declares their names."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros

PROGRAMS = {
    "simulator_node": ("sdbc_sim.nodes.simulator_node", ()),
    "controller_node": ("sdbc_sim.nodes.controller_node", ()),
    "evolution_node": ("sdbc_evolution.nodes.evolution_node", ()),
    "recorder": ("sdbc_evolution.nodes.recorder_node", ("--topics", "/task_state")),
    "characteriser_node": ("sdbc_evolution.nodes.characteriser_node", ()),
}


def run_program(
    name: str, tmp_path: Path, *ros_args: str
) -> subprocess.CompletedProcess[str]:
    module, own = PROGRAMS[name]
    if name == "recorder":
        own = ("--output", str(tmp_path / "bag"), *own)
    return subprocess.run(
        [sys.executable, "-m", module, *own, "--ros-args", *ros_args],
        env={
            **os.environ,
            "ROS_HOME": str(tmp_path / "ros_home"),
            "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
        },
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_an_undeclared_parameter_is_refused_at_start_up(name, tmp_path):
    result = run_program(name, tmp_path, "-p", "populaton:=8")
    assert result.returncode == 2, result.stderr
    # One line, and nothing before it: the node did not get going.
    [line] = result.stderr.splitlines()
    assert line.startswith(f"{name}: error: parameter populaton not declared by ")
    assert "(it declares: " in line and "use_sim_time" in line
    assert not (tmp_path / "bag").exists()  # the recorder wrote nothing


def test_a_params_file_typo_under_the_nodes_own_key_is_refused(tmp_path):
    params = tmp_path / "graph.yaml"
    params.write_text(
        yaml.safe_dump(
            {
                "/**": {"ros__parameters": {"task": "gate_escape"}},
                "simulator": {"ros__parameters": {"commnd_timeout": 2.0}},
            }
        )
    )
    result = run_program("simulator_node", tmp_path, "--params-file", str(params))
    assert result.returncode == 2, result.stderr
    assert "parameter commnd_timeout not declared by /simulator" in result.stderr
    assert "command_timeout" in result.stderr  # among the declared ones


@pytest.fixture
def context_with(tmp_path):
    """``context_with(*ros_args)``: an rclpy context initialised with those
    arguments (as a node program's), shut down at the end."""
    import rclpy

    contexts = []

    def make(*ros_args: str):
        context = rclpy.Context()
        rclpy.init(args=["test", "--ros-args", *ros_args], context=context)
        contexts.append(context)
        return context

    yield make
    for context in contexts:
        rclpy.try_shutdown(context=context)


def test_shared_keys_reach_a_node_only_as_far_as_it_declares_them(
    tmp_path, context_with
):
    from rclpy.node import Node
    from sdbc_sim.nodes.parameters import undeclared_overrides

    params = tmp_path / "graph.yaml"
    params.write_text(
        yaml.safe_dump(
            {
                "/**": {"ros__parameters": {"task": "gate_escape", "depth": 3}},
                "/**/probe": {"ros__parameters": {"genom": [1.0]}},
                "g1": {"probe": {"ros__parameters": {"nested": {"name": 1}}}},
            }
        )
    )
    ros_args = ["--params-file", str(params), "-p", "depth:=4", "-p", "extra:=1"]
    context = context_with(*ros_args)
    node = Node("probe", namespace="/g1", context=context)
    try:
        node.declare_parameter("task", "")
        # task: declared; depth: shared, but also given by -p; genom, nested.name
        # and extra: under keys naming the node, or by -p.
        argv = ["test", "--ros-args", *ros_args]
        assert undeclared_overrides(node, argv) == [
            "depth",
            "extra",
            "genom",
            "nested.name",
        ]
        without_p = ["test", "--ros-args", "--params-file", str(params)]
        assert "depth" not in undeclared_overrides(node, without_p)
    finally:
        node.destroy_node()


def test_setting_an_undeclared_parameter_at_run_time_is_refused_with_a_reason(
    context_with,
):
    from rclpy.parameter import Parameter
    from sdbc_sim.nodes.parameters import CheckedNode

    node = CheckedNode("checked", context=context_with())
    try:
        node.declare_parameter("population", 50)
        result = node.set_parameters_atomically([Parameter("populaton", value=8)])
        assert not result.successful
        assert "parameter populaton not declared by /checked" in result.reason
        assert "population" in result.reason.split("it declares:")[1]
        assert node.set_parameters_atomically([Parameter("population", value=8)])
        assert node.get_parameter("population").value == 8
    finally:
        node.destroy_node()


def test_ros2_param_set_of_an_undeclared_name_gets_the_reason(test_node):
    # What `ros2 param set /checked populaton 8` does: the SetParameters service.
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from sdbc_sim.nodes.parameters import CheckedNode

    node, executor = test_node
    checked = CheckedNode("checked_service", context=node.context)
    executor.add_node(checked)
    try:
        checked.declare_parameter("population", 50)
        client = AsyncParameterClient(node, "/checked_service")
        assert client.wait_for_services(timeout_sec=30.0)
        future = client.set_parameters([Parameter("populaton", value=8)])
        executor.spin_until_future_complete(future, timeout_sec=30.0)
        [result] = future.result().results
        assert not result.successful
        assert "parameter populaton not declared by /checked_service" in result.reason
        assert "population" in result.reason.split("it declares:")[1]
    finally:
        executor.remove_node(checked)
        checked.destroy_node()
