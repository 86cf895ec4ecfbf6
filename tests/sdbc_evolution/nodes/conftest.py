"""Running ``sdbc-graph`` as a user does, in a subprocess with this run's DDS
domain and a private ROS_HOME."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
GRAPH_TIMEOUT = 600.0
"""Seconds a whole graph run may take on a loaded two-core machine."""


@pytest.fixture
def run_graph(tmp_path: Path):
    """Runs ``python -m sdbc_evolution.graph.launch ARGS`` (``sdbc-graph``); returns the
    completed process, its output in ``stdout`` and ``stderr``."""

    def run(*args: str) -> subprocess.CompletedProcess:
        env = dict(os.environ)
        env["ROS_HOME"] = str(tmp_path / "ros_home")
        env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
        return subprocess.run(
            [sys.executable, "-m", "sdbc_evolution.graph.launch", *args],
            capture_output=True,
            text=True,
            env=env,
            cwd=ROOT,
            timeout=GRAPH_TIMEOUT,
        )

    return run


@pytest.fixture
def graph_logs():
    """A function giving every process's log in a directory, for failure
    messages."""

    def logs(directory: Path) -> str:
        return "\n".join(
            f"--- {path.name}\n{path.read_text()[-3000:]}"
            for path in sorted(directory.glob("*.log"))
        )

    return logs


@pytest.fixture
def client_node():
    """A node on a context of its own, spun by an executor in a background thread
    (what a GraphClient needs)."""
    import threading

    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node

    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("graph_test", context=context)
    executor = MultiThreadedExecutor(num_threads=3, context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield node
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(timeout=10)
