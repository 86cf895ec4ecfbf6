"""The start-up every node program shares: statuses, messages and clean-up."""

from __future__ import annotations

import argparse

import pytest

pytestmark = pytest.mark.ros


def destroyed(node) -> bool:
    from rclpy.impl.implementation_singleton import rclpy_implementation

    try:
        node.get_name()
    except rclpy_implementation.InvalidHandle:
        return True
    return False


def program(**changes):
    from rclpy.node import Node
    from sdbc_sim.nodes.startup import NodeProgram

    made: list[Node] = []

    def make_nodes(startup):
        for name in ("first", "second"):
            node = Node(f"startup_test_{name}")
            made.append(node)
            yield node

    settings = {
        "name": "test_node",
        "make_nodes": make_nodes,
        "serve": lambda startup, nodes: len(nodes) + 40,
        # Leave this process's signal handlers (pytest's) alone.
        "signals": "own",
        **changes,
    }
    return NodeProgram(**settings), made


def test_the_status_is_what_serve_returns_and_every_node_is_destroyed(ros_home):
    from sdbc_sim.nodes.startup import run_node_program

    spec, made = program()
    assert run_node_program(spec, ["test_node"]) == 42
    assert len(made) == 2 and all(destroyed(node) for node in made)


def test_bad_input_exits_2_naming_the_program(ros_home, capsys):
    from sdbc_sim.nodes.startup import run_node_program

    def refuse(startup):
        raise ValueError("parameter x: must be positive")

    spec, _ = program(make_nodes=refuse)
    assert run_node_program(spec, ["test_node"]) == 2
    assert "test_node: error: parameter x: must be positive" in capsys.readouterr().err
    spec, _ = program()
    assert run_node_program(spec, ["test_node", "stray"]) == 2
    assert "test_node: error: unknown arguments ['stray']" in capsys.readouterr().err


def test_own_arguments_are_parsed_and_nodes_made_before_a_failure_are_destroyed(
    ros_home,
):
    from rclpy.node import Node
    from sdbc_sim.nodes.startup import run_node_program

    parser = argparse.ArgumentParser(prog="test_node")
    parser.add_argument("--count", type=int)
    made: list[Node] = []

    def make_nodes(startup):
        for k in range(startup.args.count):
            if k == 2:
                raise ValueError("the third node fails")
            made.append(Node(f"startup_test_{k}"))
            yield made[-1]

    spec, _ = program(make_nodes=make_nodes, parser=parser)
    argv = ["test_node", "--count", "3", "--ros-args", "-p", "use_sim_time:=false"]
    assert run_node_program(spec, argv) == 2
    assert len(made) == 2 and all(destroyed(node) for node in made)


def test_sigusr1_writes_the_stacks_to_the_original_stderr_when_stderr_has_no_file(
    monkeypatch, capfd
):
    """A ``sys.stderr`` without a file descriptor (a notebook's, a test's
    capture) does not stop a node program: SIGUSR1's stacks go to the
    interpreter's original stderr, and the process goes on."""
    import faulthandler
    import io
    import os
    import signal
    import sys

    from sdbc_sim.nodes.startup import stacks_on_sigusr1

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    try:
        stacks_on_sigusr1()
        os.kill(os.getpid(), signal.SIGUSR1)
    finally:
        faulthandler.unregister(signal.SIGUSR1)
    err = capfd.readouterr().err
    assert "(most recent call first)" in err and "test_startup.py" in err
