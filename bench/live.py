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

The trials are checked to be identical (fitness and length). The last line reads
``LIVE lockstep-steps/s=N unobserved=U batched=M stepper=S target=500 ok|below``
with N the observed figure.

Run: ``scripts/sdbc bench live`` (options: ``--task``, ``--steps``, ``--repeat``,
``--robots-per-process``, ``--seed``, ``--marker-period``).
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


def main() -> None:
    args = parse_args()
    # A graph of its own: this machine only, a domain no other graph is likely on.
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
    from sdbc_sim.tasks import make_task

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


if __name__ == "__main__":
    main()
