"""``sdbc-graph``: the whole live graph of a task as processes, from one YAML file.

The graph file (:mod:`sdbc_evolution.graph.graph_file`) names the task and every
node's parameters; the launcher starts the simulator, the controllers, and
optionally the evolution node and a bag recorder, each as its own process
(:mod:`sdbc_evolution.graph.processes`).

It then waits: for Ctrl-C, for a node process to exit (which stops the graph), or,
with ``--trial SEED`` (repeatable), for those trials, which it asks the simulator
for and reports, and stops. Stopping sends SIGINT to every process, gives each
``shutdown_timeout`` seconds, kills what is left, and removes the shared-memory
files that Fast DDS leaves in ``/dev/shm`` (:mod:`sdbc_evolution.graph.shm`).

Examples::

    sdbc-graph configs/ros/gate_escape.yaml
    sdbc-graph configs/ros/gate_escape.yaml --trial 7 --record bags/trial_7
    sdbc-graph configs/ros/evolution.yaml

Exit status: 0 done, 1 a node process failed or a trial was aborted, 2 bad input,
130 interrupted.
"""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sdbc_evolution.graph.graph_file import (
    CONTROLLERS_KEY,
    GraphError,
    LaunchSettings,
    has_genome,
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
        "--log-dir",
        type=Path,
        help="write each process's output to DIR/<name>.log instead of the terminal",
    )
    return parser


def _wait_until_ready(
    graph: ProcessGraph, node: Any, client: Any, record: bool, timeout: float
) -> None:
    """Waits for the simulator's service and, when recording, for the recorder's
    ``recorder/ready`` (every recorded topic matched to all its publishers)."""
    import rclpy
    from sdbc_sim.nodes.interface import LATCHED_QOS, RECORDER_READY_TOPIC
    from std_msgs.msg import Bool

    deadline = time.monotonic() + timeout
    recorder = []
    node.create_subscription(
        Bool, RECORDER_READY_TOPIC, lambda m: recorder.append(m.data), LATCHED_QOS
    )
    while not (client.service_is_ready() and (not record or any(recorder))):
        if dead := graph.exited():
            raise RuntimeError(f"node processes ended before the first trial: {dead}")
        if time.monotonic() > deadline:
            raise RuntimeError(
                f"the graph did not come up within {timeout:g} s (simulator service "
                f"ready: {client.service_is_ready()}"
                + (f", recorder ready: {any(recorder)}" if record else "")
                + ")"
            )
        rclpy.spin_once(node, timeout_sec=0.1)


def run_trials(
    graph: ProcessGraph, seeds: Sequence[int], record: bool, settings: LaunchSettings
) -> int:
    """Asks the simulator for one trial per seed and prints each answer; 0 if all
    ran, 1 otherwise."""
    import rclpy
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from sdbc_sim.nodes.interface import RUN_TRIAL_SERVICE

    from sdbc_msgs.srv import RunTrial

    # Ctrl-C stays a KeyboardInterrupt here: the launcher then stops the graph.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node("graph_launcher")
    status = 0
    try:
        client = node.create_client(RunTrial, RUN_TRIAL_SERVICE)
        _wait_until_ready(graph, node, client, record, settings.ready_timeout)
        for seed in seeds:
            future = client.call_async(RunTrial.Request(seed=seed))
            rclpy.spin_until_future_complete(
                node, future, timeout_sec=settings.trial_timeout
            )
            answer = future.result()
            if answer is None:
                print(
                    f"trial seed {seed}: no answer within {settings.trial_timeout:g} s"
                )
                status = 1
            elif not answer.success:
                print(f"trial seed {seed}: aborted: {answer.message}")
                status = 1
            else:
                print(
                    f"trial seed {seed}: fitness {answer.fitness:.6g}, length "
                    f"{answer.length}, characterisation "
                    f"{[round(v, 6) for v in answer.characterisation]}"
                )
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """``sdbc-graph``: brings the graph up, and down on Ctrl-C; the exit status."""
    args = build_parser().parse_args(argv)
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
        with tempfile.TemporaryDirectory(prefix="sdbc-graph-") as tmp:
            graph = ProcessGraph.from_graph_file(
                graph_file, Path(tmp), args.record, args.log_dir
            )
            return _run(graph, args, graph_file.settings)
    except GraphError as error:
        print(f"sdbc-graph: error: {error}", file=sys.stderr)
        return 2


def _run(
    graph: ProcessGraph, args: argparse.Namespace, settings: LaunchSettings
) -> int:
    names = ", ".join(graph.processes)
    print(f"sdbc-graph: starting {names}", file=sys.stderr)
    status = 0
    graph.start()
    try:
        if args.trial:
            status = run_trials(graph, args.trial, args.record is not None, settings)
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
