"""Lockstep speed of the live ROS 2 graph, beside the batched engine, in one run.

The graph: ``simulator_node`` and one ``controller_node`` process per robot (four
for gate escape), started by the graph launcher, DDS on localhost. The same
single trial (same genome, same seed) is then run:

- live: through the simulator's ``run_trial`` service, in lockstep with the
  controller processes; steps/s = trial length / wall time of the call, median
  over ``--repeat`` trials; first with nobody watching (the simulator then skips
  building the task state and markers), then "observed", with the project's
  recorder (a process of its own) writing both to a bag, which is checked to
  hold every step (the target's figure);
- stepper: the engine's one-trial stepper driven in this process with the
  network computed here (what the simulator does, without DDS);
- batched: :func:`sdbc_sim.run_batch` on that one trial.

The trials are checked to be identical (fitness and length). Its line reads
``LIVE lockstep-steps/s=N unobserved=U batched=M stepper=S target=500 ok|below``
with N the observed figure.

Then live evaluation on several graphs: one generation-sized batch (``--population``
genomes, ``--trials`` each) evaluated by the evolution node's
:class:`~sdbc_evolution.graph.live_evaluator.LiveEvaluator` through K simulator
graphs (``sdbc-graph``'s ``graphs: K``: a simulator and one controller process for
the team each), for each K of ``--graphs`` (default 1 2 4); the evaluations are
checked to be identical, and the line ``GRAPHS K=... s/generation=... speed-up=...``
gives each K's wall time and its speed-up over one graph. On this two-core machine
K graphs share two cores, so the speed-up is bounded by what lockstep leaves idle
(waiting on DDS round trips), not by K.

Run: ``scripts/sdbc bench live`` (options: ``--task``, ``--steps``, ``--repeat``,
``--robots-per-process``, ``--seed``, ``--marker-period``, ``--graphs``,
``--population``, ``--trials``; ``--graphs`` with no value skips that part).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

TARGET = 500.0
"""Lockstep steps per second the live graph should reach with 4 controllers."""


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="gate_escape")
    parser.add_argument(
        "--steps", type=int, default=1000, help="max_steps of the trial (default 1000)"
    )
    parser.add_argument("--repeat", type=int, default=3, help="live trials timed")
    parser.add_argument("--robots-per-process", type=int, default=1)
    parser.add_argument("--seed", type=int, default=1, help="the trial's seed")
    parser.add_argument(
        "--marker-period", type=int, default=10, help="simulator's marker_period"
    )
    parser.add_argument(
        "--graphs",
        type=int,
        nargs="*",
        default=[1, 2, 4],
        help="numbers of simulator graphs a generation is spread over (default 1 2 4)",
    )
    parser.add_argument(
        "--population", type=int, default=8, help="genomes of the generation"
    )
    parser.add_argument("--trials", type=int, default=2, help="trials per genome")
    return parser.parse_args()


def long_genome(task, seed: int, candidates: int = 16) -> np.ndarray:
    """A random genome whose trial lasts longest: the timing then covers the
    most steps."""
    from sdbc_sim.engine import run_batch

    genomes = np.random.default_rng(0).uniform(
        -1.0, 1.0, (candidates, task.genome_length)
    )
    result = run_batch(task, genomes, np.full((candidates, 1), seed))
    return genomes[int(np.argmax(result.length[:, 0]))]


def time_batched(task, genome: np.ndarray, seed: int) -> tuple[float, float, int]:
    """(steps/s, fitness, length) of the batched engine on the one trial."""
    from sdbc_sim.engine import run_batch

    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        result = run_batch(task, genome[None], np.array([[seed]]))
        best = min(best, time.perf_counter() - t0)
    length = int(result.length[0, 0])
    return length / best, float(result.fitness[0, 0]), length


def time_stepper(task, genome: np.ndarray, seed: int) -> float:
    """Steps/s of the one-trial stepper with the network computed in process."""
    from sdbc_sim.engine import TrialStepper
    from sdbc_sim.network import forward

    stepper = TrialStepper(task)
    stepper.reset(seed)
    t0 = time.perf_counter()
    while not stepper.done:
        stepper.step(forward(genome, task.network, stepper.sensors()))
    return stepper.step_count / (time.perf_counter() - t0)


def run_trials(client, args, count: int) -> list[tuple[float, float, int]]:
    """(steps/s, fitness, length) of ``count`` trials asked of the simulator."""
    from sdbc_msgs.srv import RunTrial

    results = []
    for _ in range(count):
        t0 = time.perf_counter()
        future = client.call_async(RunTrial.Request(seed=args.seed))
        while not future.done():
            time.sleep(0.001)
        seconds = time.perf_counter() - t0
        answer = future.result()
        if not answer.success:
            sys.exit(f"live trial aborted: {answer.message}")
        results.append((answer.length / seconds, answer.fitness, answer.length))
    return results


def time_live(args, genome: np.ndarray, tmp: Path) -> dict[str, list]:
    """Live trials, {"unobserved": [...], "observed": [...]}: first with nobody
    subscribed to the task state and markers (the simulator then skips building
    them), then with the project's recorder writing both to a bag, as when a
    trial is recorded or watched. Each entry is (steps/s, fitness, length)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rosbags.highlevel import AnyReader
    from sdbc_evolution.graph.graph_file import load_graph_file, trial_graph
    from sdbc_evolution.graph.processes import ProcessGraph, child_environment
    from sdbc_sim.nodes.interface import LATCHED_QOS, RECORDER_READY_TOPIC
    from std_msgs.msg import Bool

    from sdbc_msgs.srv import RunTrial

    graph_file = tmp / "graph.yaml"
    graph_file.write_text(
        yaml.safe_dump(
            trial_graph(
                args.task,
                genome,
                {"max_steps": args.steps},
                launcher={
                    "robots_per_process": args.robots_per_process,
                    "record_topics": ["/task_state", "/markers"],
                },
                nodes={"simulator": {"marker_period": args.marker_period}},
            )
        )
    )
    env = child_environment()
    env.setdefault("ROS_HOME", str(tmp / "ros_home"))
    bag = tmp / "bag"
    graph = ProcessGraph.from_graph_file(
        load_graph_file(graph_file), tmp, record=bag, log_dir=tmp / "logs", env=env
    )
    results: dict[str, list] = {}
    for name in graph.processes:
        if name != "recorder":
            graph.start(name)
    try:
        rclpy.init()
        node = Node("bench_live")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        recorder_ready = threading.Event()
        node.create_subscription(
            Bool,
            RECORDER_READY_TOPIC,
            lambda m: m.data and recorder_ready.set(),
            LATCHED_QOS,
        )
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        try:
            client = node.create_client(RunTrial, "run_trial")
            if not client.wait_for_service(timeout_sec=60.0):
                sys.exit(f"the simulator did not come up; logs in {tmp / 'logs'}")
            run_trials(client, args, 1)  # warm-up: discovery, first allocations
            results["unobserved"] = run_trials(client, args, args.repeat)
            graph.start("recorder")
            # Ready: every recorded topic matched to its publishers (the simulator
            # then also waits for its side of the match before a trial's step 1).
            if not recorder_ready.wait(60.0):
                sys.exit(f"the recorder did not come up; logs in {tmp / 'logs'}")
            results["observed"] = run_trials(client, args, args.repeat)
        finally:
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown()
    finally:
        graph.stop()
    expected = sum(length for _, _, length in results["observed"])
    with AnyReader([bag]) as reader:
        recorded = sum(
            c.msgcount for c in reader.connections if c.topic == "/task_state"
        )
    if recorded != expected:
        sys.exit(f"task state messages: {recorded} recorded, {expected} published")
    return results


def time_graphs(args, task, tmp: Path) -> dict[int, tuple[float, dict]]:
    """{K: (seconds, evaluation)} of one generation-sized batch evaluated through
    K simulator graphs, for each K of ``--graphs``."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node
    from sdbc_evolution.graph.client import GraphClient
    from sdbc_evolution.graph.graph_file import (
        graph_namespaces,
        load_graph_file,
        trial_graph,
    )
    from sdbc_evolution.graph.live_evaluator import LiveEvaluator
    from sdbc_evolution.graph.processes import ProcessGraph, child_environment
    from sdbc_evolution.run.evaluators import TaskSpec

    rng = np.random.default_rng(args.seed)
    genomes = rng.uniform(-1.0, 1.0, (args.population, task.genome_length))
    seeds = rng.integers(0, 2**31 - 1, (args.population, args.trials))
    config = {"max_steps": args.steps}
    spec = TaskSpec(args.task, config)
    results = {}
    rclpy.init()
    node = Node("bench_live_graphs")
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        for k in args.graphs:
            work = tmp / f"graphs{k}"
            work.mkdir()
            path = work / "graph.yaml"
            path.write_text(
                yaml.safe_dump(
                    trial_graph(
                        args.task,
                        genomes[0],
                        config,
                        launcher={
                            "graphs": k,
                            "robots_per_process": task.layout.n_controlled,
                        },
                    )
                )
            )
            graph_file = load_graph_file(path)
            env = child_environment()
            env.setdefault("ROS_HOME", str(tmp / "ros_home"))
            namespace = f"bench{k}"
            graph = ProcessGraph.from_graph_file(
                graph_file, work, log_dir=work / "logs", env=env, namespace=namespace
            )
            graph.start()
            try:
                clients = [
                    GraphClient(
                        node,
                        task,
                        args.task,
                        config,
                        timeout=120.0,
                        namespace="/" + "/".join(p for p in (namespace, sub) if p),
                    )
                    for sub in graph_namespaces(graph_file.settings)
                ]
                for client in clients:
                    client.wait_for_graph(120.0)
                with LiveEvaluator(spec, clients) as evaluator:
                    evaluator.evaluate(genomes[:1], seeds[:1, :1])  # warm-up
                    t0 = time.perf_counter()
                    evaluation = evaluator.evaluate(genomes, seeds)
                    results[k] = (time.perf_counter() - t0, evaluation)
            finally:
                graph.stop()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return results


def report_graphs(args, task, tmp: Path) -> None:
    results = time_graphs(args, task, tmp)
    first = min(results)
    reference = results[first][1]
    for k, (_, evaluation) in results.items():
        for name in ("fitness", "trial_fitness"):
            if not np.array_equal(getattr(evaluation, name), getattr(reference, name)):
                sys.exit(f"{k} graphs: {name} differs from {first} graph(s)")
        for key, values in evaluation.behaviours.items():
            if not np.array_equal(values, reference.behaviours[key]):
                sys.exit(f"{k} graphs: behaviour {key} differs from {first} graph(s)")
    print(
        f"{args.task}: a generation of {args.population} genomes x {args.trials} "
        f"trials (max_steps {args.steps}) through K simulator graphs, "
        f"{os.cpu_count()} cores; evaluations identical"
    )
    base = results[first][0]
    for k, (seconds, _) in sorted(results.items()):
        print(
            f"  K={k}: {seconds:7.1f} s per generation, speed-up "
            f"{base / seconds:4.2f} over K={first}"
        )
    print(
        "GRAPHS "
        + " ".join(
            f"K={k}:s/generation={seconds:.1f},speed-up={base / seconds:.2f}"
            for k, (seconds, _) in sorted(results.items())
        )
    )


def main() -> None:
    args = parse_args()
    # A graph of its own: this machine only, a domain no other graph is likely on.
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
    from sdbc_sim.nodes.startup import keep_dds_on_loopback
    from sdbc_sim.tasks import make_task

    keep_dds_on_loopback()

    task = make_task(args.task, max_steps=args.steps)
    genome = long_genome(task, args.seed)
    batched, fitness, length = time_batched(task, genome, args.seed)
    stepper = time_stepper(task, genome, args.seed)
    n_controllers = -(-task.layout.n_controlled // args.robots_per_process)
    print(
        f"{args.task}: one trial, seed {args.seed}, {length} steps, "
        f"{task.layout.n_controlled} robots, {n_controllers} controller processes"
    )
    with tempfile.TemporaryDirectory(prefix="bench-live-") as tmp:
        live = time_live(args, genome, Path(tmp))
    medians = {}
    for mode, trials in live.items():
        for _, live_fitness, live_length in trials:
            if live_length != length or abs(live_fitness - fitness) > 1e-9:
                sys.exit(
                    f"live trial differs from the batched one: fitness {live_fitness} "
                    f"vs {fitness}, length {live_length} vs {length}"
                )
        rates = [r for r, _, _ in trials]
        medians[mode] = statistics.median(rates)
        print(
            f"  live lockstep, task state {mode:10s}: {medians[mode]:6.0f} steps/s "
            f"(trials: {', '.join(f'{r:.0f}' for r in rates)})"
        )
    print(f"  stepper (in process, no DDS)          : {stepper:6.0f} steps/s")
    print(f"  batched engine (run_batch, one trial) : {batched:6.0f} steps/s")
    observed = medians["observed"]
    verdict = "ok" if observed >= TARGET else "below"
    print(
        f"LIVE lockstep-steps/s={observed:.0f} unobserved={medians['unobserved']:.0f} "
        f"batched={batched:.0f} stepper={stepper:.0f} target={TARGET:.0f} {verdict}"
    )
    if args.graphs:
        with tempfile.TemporaryDirectory(prefix="bench-live-graphs-") as tmp:
            report_graphs(args, task, Path(tmp))


if __name__ == "__main__":
    main()
