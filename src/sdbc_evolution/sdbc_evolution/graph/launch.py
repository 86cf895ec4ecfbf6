"""``sdbc-graph``: the whole live graph of a task as processes, from one YAML file.

The graph file (:mod:`sdbc_evolution.graph.graph_file`) names the task and every
node's parameters; the launcher starts the simulator, the controllers, and
optionally the evolution node and a bag recorder, each as its own process
(:mod:`sdbc_evolution.graph.processes`).

Before it starts anything it looks, for a moment, whether a node of the DDS domain
already offers its simulator's service (another graph in the same namespace, whose
answers would be taken for this one's), and refuses if so (exit 2).

It then waits: for Ctrl-C, for a node process to exit (which stops the graph), or,
with ``--trial SEED`` (repeatable), for those trials, which it asks the simulator
for and reports, and stops. Before the first trial it checks, as the evolution
node does, that one simulator alone answers and that it runs the graph file's task
with its settings and physics model (:class:`~sdbc_evolution.graph.client.
GraphClient`). Stopping sends SIGINT to every process, gives each
``shutdown_timeout`` seconds, kills what is left, and removes the shared-memory
files that Fast DDS leaves in ``/dev/shm`` (:mod:`sdbc_evolution.graph.shm`). If
the launcher itself is killed, every node stops on its own
(:mod:`sdbc_evolution.graph.owned`).

``--namespace NS`` pushes the whole graph into NS (``/NS/simulator``,
``/NS/robot_0/controller``, ``/NS/task_state``, ...), so that several graphs share
one DDS domain. With ``graphs: K`` in the ``sdbc_graph`` section, K simulator
graphs run side by side (namespaces ``graph_0`` ... below NS) and the evolution
node spreads each generation over them; ``--trial`` then runs on ``graph_0``.

Examples::

    sdbc-graph configs/ros/gate_escape.yaml
    sdbc-graph configs/ros/gate_escape.yaml --trial 7 --record bags/trial_7
    sdbc-graph configs/ros/gate_escape.yaml --namespace team_a --trial 7
    sdbc-graph configs/ros/evolution.yaml

Exit status: 0 done, 1 a node process failed or a trial was aborted, 2 bad input,
130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sdbc_evolution.graph.graph_file import (
    CONTROLLERS_KEY,
    GraphError,
    GraphFile,
    check_namespace,
    graph_namespaces,
    has_genome,
    join_namespace,
    load_graph_file,
)
from sdbc_evolution.graph.processes import ProcessGraph
from sdbc_evolution.run.stopping import stoppable


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``sdbc-graph``."""
    parser = argparse.ArgumentParser(
        prog="sdbc-graph",
        description=(
            "Bring up the live ROS 2 graph of a task (simulator, one controller per "
            "robot, optionally the evolution node and a bag recorder) as processes, "
            "with parameters from a graph file; Ctrl-C stops it cleanly."
        ),
    )
    parser.add_argument("graph", type=Path, help="graph file (YAML), see configs/ros/")
    parser.add_argument(
        "--trial",
        type=int,
        action="append",
        metavar="SEED",
        help="run a trial with this seed, report it, and stop (repeatable)",
    )
    parser.add_argument(
        "--record", type=Path, metavar="BAG", help="record the graph's topics to BAG"
    )
    parser.add_argument(
        "--namespace",
        default="",
        metavar="NS",
        help="push every node of the graph into the namespace NS",
    )
    parser.add_argument(
        "--log-dir",
        type=Path,
        help="write each process's output to DIR/<name>.log instead of the terminal",
    )
    return parser


def _wait_for_recorder(graph: ProcessGraph, node: Any, timeout: float) -> None:
    """Waits for the recorder's ``recorder/ready`` (every recorded topic matched
    to all its publishers)."""
    from sdbc_sim.nodes.interface import LATCHED_QOS, RECORDER_READY_TOPIC
    from std_msgs.msg import Bool

    ready = threading.Event()

    def on_ready(msg: Bool) -> None:
        if msg.data:
            ready.set()

    node.create_subscription(Bool, RECORDER_READY_TOPIC, on_ready, LATCHED_QOS)
    deadline = time.monotonic() + timeout
    while not ready.wait(0.1):
        if dead := graph.exited():
            raise RuntimeError(f"node processes ended before the first trial: {dead}")
        if time.monotonic() > deadline:
            raise RuntimeError(f"the recorder was not ready within {timeout:g} s")


DISCOVERY_WAIT = 5.0
"""Seconds the launcher looks for another graph in its namespace before starting:
on one machine, a new participant learnt a running graph's services in 0.4 to
2.0 s with two study processes busy on both cores."""


def busy_simulators(namespace: str, graph_file: GraphFile) -> list[str]:
    """The simulator services of this graph's namespaces that some node already
    serves in the DDS domain (another graph, whose answers would be taken for this
    one's), looked for during :data:`DISCOVERY_WAIT` seconds."""
    import rclpy
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from sdbc_sim.nodes.interface import RUN_TRIAL_SERVICE

    wanted = {
        "/" + join_namespace(namespace, sub, RUN_TRIAL_SERVICE)
        for sub in graph_namespaces(graph_file.settings)
    }
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = Node("graph_launcher_probe", context=context)
        deadline = time.monotonic() + DISCOVERY_WAIT
        busy: set[str] = set()
        while not busy and time.monotonic() < deadline:
            time.sleep(0.1)
            # Servers alone: the service names of the graph also list a name whose
            # only end is a client, such as an evolution node or a conformance
            # check waiting for this very graph.
            busy = {name for name in wanted if node.count_services(name) > 0}
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    return sorted(busy)


def run_trials(
    graph: ProcessGraph,
    graph_file: GraphFile,
    seeds: Sequence[int],
    record: bool,
    namespace: str = "",
) -> int:
    """Asks the simulator of ``graph`` (its first simulator graph, if several)
    for one trial per seed and prints each answer; 0 if all ran, 1 otherwise.

    The graph is checked first as the evolution node checks it: every controller
    there, one simulator alone, running the graph file's task and settings."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from sdbc_sim.tasks import make_task

    from sdbc_evolution.graph.client import GraphClient, GraphClientError

    settings = graph_file.settings
    # Ctrl-C stays a KeyboardInterrupt here: the launcher then stops the graph.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node("graph_launcher", namespace="/" + namespace)
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    status = 0
    try:
        client = GraphClient(
            node,
            make_task(graph_file.task, **graph_file.task_config),
            graph_file.task,
            graph_file.task_config,
            timeout=settings.trial_timeout,
            physics=graph_file.section("simulator").get("physics_model"),
            namespace=graph_namespaces(settings)[0],
        )
        if record:
            _wait_for_recorder(graph, node, settings.ready_timeout)
        try:
            client.wait_for_graph(settings.ready_timeout)
        except GraphClientError as error:
            raise RuntimeError(str(error)) from None
        for seed in seeds:
            if dead := graph.exited():
                raise RuntimeError(f"node processes ended: {dead}")
            try:
                answer = client.run_trial(seed)
            except GraphClientError as error:
                print(f"trial seed {seed}: failed: {error}")
                status = 1
                continue
            print(
                f"trial seed {seed}: fitness {answer.fitness:.6g}, length "
                f"{answer.length}, characterisation "
                f"{[round(float(v), 6) for v in answer.characterisation]}"
            )
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        spinner.join(timeout=5.0)
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """``sdbc-graph``: brings the graph up, and down on Ctrl-C; the exit status."""
    args = build_parser().parse_args(argv)
    # This process joins the graph too (--trial, the recorder's readiness): it
    # keeps to loopback as the nodes it starts do, before rclpy reads the range.
    from sdbc_sim.nodes.startup import keep_dds_on_loopback

    keep_dds_on_loopback()
    with stoppable():
        return _main(args)


def _main(args: argparse.Namespace) -> int:
    try:
        graph_file = load_graph_file(args.graph)
        if (
            args.trial
            and not graph_file.settings.evolution
            and not has_genome(graph_file)
        ):
            raise GraphError(
                f"graph file {args.graph}: --trial needs a genome for the controllers "
                f"('{CONTROLLERS_KEY}: {{ros__parameters: {{genome: [...]}}}}')"
            )
        if args.record is not None and args.record.exists():
            raise GraphError(f"--record: {args.record} exists already; not overwriting")
        if args.trial and any(seed < 0 for seed in args.trial):
            raise GraphError(f"--trial: seeds must be non-negative, got {args.trial}")
        try:
            args.namespace = check_namespace(args.namespace)
        except GraphError as error:
            raise GraphError(f"--namespace: {error}") from None
        with tempfile.TemporaryDirectory(prefix="sdbc-graph-") as tmp:
            graph = ProcessGraph.from_graph_file(
                graph_file,
                Path(tmp),
                args.record,
                args.log_dir,
                namespace=args.namespace,
            )
            return _run(graph, args, graph_file)
    except GraphError as error:
        print(f"sdbc-graph: error: {error}", file=sys.stderr)
        return 2


def _run(graph: ProcessGraph, args: argparse.Namespace, graph_file: GraphFile) -> int:
    names = ", ".join(graph.processes)
    where = f" in /{args.namespace}" if args.namespace else ""
    if busy := busy_simulators(args.namespace, graph_file):
        domain = os.environ.get("ROS_DOMAIN_ID", "0")
        print(
            f"sdbc-graph: error: another graph runs in ROS_DOMAIN_ID {domain}: "
            f"{', '.join(busy)} is offered already; give this graph a namespace of "
            "its own (--namespace) or another ROS_DOMAIN_ID",
            file=sys.stderr,
        )
        return 2
    print(f"sdbc-graph: starting {names}{where}", file=sys.stderr)
    status = 0
    graph.start()
    try:
        if args.trial:
            status = run_trials(
                graph, graph_file, args.trial, args.record is not None, args.namespace
            )
        else:
            while not (ended := graph.exited()):
                time.sleep(0.2)
            # A node that finishes its work (the evolution node at the end of its
            # run) ends the graph; one that fails ends it with an error.
            print(f"sdbc-graph: node process ended: {ended}; stopping", file=sys.stderr)
            status = 0 if all(code == 0 for code in ended.values()) else 1
    except KeyboardInterrupt:
        status = 130
    except RuntimeError as error:
        print(f"sdbc-graph: error: {error}", file=sys.stderr)
        status = 1
    finally:
        codes = graph.stop()
    failed = {n: c for n, c in codes.items() if c not in (0, -signal.SIGINT)}
    if failed and status == 0:
        print(f"sdbc-graph: processes failed: {failed}", file=sys.stderr)
        status = 1
    if args.record is not None:
        print(f"sdbc-graph: bag in {args.record}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
