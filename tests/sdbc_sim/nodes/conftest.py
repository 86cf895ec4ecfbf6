"""A live graph (simulator and controllers as processes) and a client node to
drive it, shared by the tests of a module."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

GRAPH_TIMEOUT = 60.0
"""Seconds a graph may take to come up on a loaded two-core machine."""
CANDIDATES = 32
"""Random genomes among which a test picks the best, so that trials do something."""


def best_random_genome(task: Any, seeds: np.ndarray, rng_seed: int = 0) -> np.ndarray:
    """The best of :data:`CANDIDATES` uniform random genomes on ``seeds`` (batched
    engine): a controller that does something (robots escape, charge, chase)."""
    from sdbc_sim.engine import run_batch

    genomes = np.random.default_rng(rng_seed).uniform(
        -1.0, 1.0, (CANDIDATES, task.genome_length)
    )
    result = run_batch(task, genomes, np.tile(seeds, (CANDIDATES, 1)))
    return genomes[int(np.argmax(result.controller_fitness))]


@dataclass
class LiveGraph:
    """A running graph and the means to drive it.

    Attributes:
        graph: The node processes.
        client: A graph client on the test's node.
        node: The test's node (spun in a background thread).
        task: The task object (the same settings as the graph's).
        task_name: Its name.
        task_config: Its overrides.
        genome: The genome the graph file gives the controllers.
        log_dir: Where the processes write their output.
    """

    graph: Any
    client: Any
    node: Any
    task: Any
    task_name: str
    task_config: dict
    genome: np.ndarray
    log_dir: Path

    def logs(self) -> str:
        """Every process's output, for failure messages."""
        return "\n".join(
            f"--- {p.name}\n{p.read_text()[-3000:]}"
            for p in sorted(self.log_dir.glob("*"))
        )


def start_live_graph(
    tmp: Path,
    task_name: str,
    task_config: dict,
    genome: np.ndarray,
    robots_per_process: int = 1,
    simulator: dict | None = None,
) -> Iterator[LiveGraph]:
    """Starts a graph from a graph file written to ``tmp`` and a client node;
    yields a :class:`LiveGraph`; stops everything."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node
    from sdbc_evolution.graph.client import GraphClient
    from sdbc_evolution.graph.graph_file import load_graph_file, trial_graph
    from sdbc_evolution.graph.processes import ProcessGraph, child_environment
    from sdbc_sim.tasks import make_task

    graph_file = tmp / "graph.yaml"
    graph_file.write_text(
        yaml.safe_dump(
            trial_graph(
                task_name,
                genome,
                task_config,
                launcher={"robots_per_process": robots_per_process},
                nodes={
                    "simulator": {
                        # Longer than Fast DDS needs to free its shared-memory
                        # port after a controller is SIGKILLed mid-write (seen:
                        # the other robots' commands then stall for up to ~2 s).
                        "command_timeout": 6.0,
                        "discovery_timeout": 10.0,
                        **(simulator or {}),
                    }
                },
            )
        )
    )
    env = child_environment()
    env["ROS_HOME"] = str(tmp / "ros_home")
    log_dir = tmp / "logs"
    graph = ProcessGraph.from_graph_file(
        load_graph_file(graph_file), tmp, log_dir=log_dir, env=env
    )
    graph.start()
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("test_client", context=context)
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    task = make_task(task_name, **task_config)
    client = GraphClient(node, task, task_name, task_config, timeout=GRAPH_TIMEOUT)
    live = LiveGraph(graph, client, node, task, task_name, task_config, genome, log_dir)
    try:
        try:
            client.wait_for_graph(GRAPH_TIMEOUT)
        except Exception as error:
            raise RuntimeError(f"{error}\n{live.logs()}") from None
        yield live
    finally:
        client.stop.set()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(timeout=10)
        codes = graph.stop()
        # Every process still running at the end must stop cleanly on SIGINT.
        assert all(c in (0, -9) for c in codes.values()), (codes, live.logs())


@pytest.fixture(scope="module")
def gate_escape_graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveGraph]:
    """Gate escape with trials of at most 300 steps, 4 controllers in 4 processes,
    a controller that lets robots escape."""
    from sdbc_sim.tasks import make_task

    config = {"max_steps": 300}
    genome = best_random_genome(make_task("gate_escape", **config), np.array([1, 2, 3]))
    yield from start_live_graph(
        tmp_path_factory.mktemp("gate_escape_graph"), "gate_escape", config, genome
    )


@pytest.fixture
def start_node(tmp_path: Path):
    """``start_node(module, *args)``: a node program started as a process (module
    run with ``python -m``), output on its stdout, with this test's ROS_HOME and
    import path; every one still running at the end is killed, after SIGUSR1 and
    a second to write its threads' stacks, which the end of the test prints (so a
    hung node's report says where it hung)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    started: list[subprocess.Popen[str]] = []

    def start(module: str, *args: str) -> subprocess.Popen[str]:
        process = subprocess.Popen(
            [sys.executable, "-m", module, *args],
            env={
                **os.environ,
                "ROS_HOME": str(tmp_path / "ros_home"),
                "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
            },
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        started.append(process)
        return process

    yield start
    hung = [process for process in started if process.poll() is None]
    for process in hung:
        process.send_signal(signal.SIGUSR1)
    if hung:
        time.sleep(1.0)
    for process in hung:
        process.kill()
        output = process.communicate()[0]
        print(f"still running at the end: {' '.join(process.args)}\n{output}")


@pytest.fixture
def test_node():
    """``(node, executor)``: a node of this test in a context of its own, spun by
    the test (``executor.spin_once``), shut down at the end."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("node_test", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    yield node, executor
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
