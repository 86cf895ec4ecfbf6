"""Tutorial 06: evolve controllers through a ROS 2 system of your own.

Starts ``point_chase_simulator.py`` (a simulator and two controller nodes written
against the evolution node's contract, with nothing of sdbc_sim), then the evolution
node with the live evaluator, told the team size and the genome length of a task it
does not know. The node learns the SDBC's dimensions from the first trial's
``task_state`` messages and evolves; this script prints its per-generation log.

    python examples/06_ros2_system/evolve.py --out results/06
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from point_chase_simulator import GENOME_LENGTH, ROBOTS, TASK  # noqa: E402

EXPERIMENT = {
    "task": TASK,
    "treatment": "ns-sd+",
    "generations": 4,
    "seed": 5,
    "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
    "novelty": {"k": 3},
    "evaluation": {"trials": 2, "reevaluation_trials": 0},
}
"""A small experiment: NS-SD+ on point chase, every trial run by the simulator."""


def evolve(out: Path, timeout: float = 600.0) -> int:
    """Runs the experiment through the graph; the exit status of the evolution node."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    with tempfile.TemporaryDirectory() as scratch:
        experiment = Path(scratch) / "experiment.yaml"
        experiment.write_text(yaml.safe_dump(EXPERIMENT))
        simulator = subprocess.Popen(
            [sys.executable, str(HERE / "point_chase_simulator.py")], env=env
        )
        try:
            node = [sys.executable, "-m", "sdbc_evolution.nodes.evolution_node"]
            node += ["--ros-args", "-p", f"task:={TASK}", "-p", "evaluator:=live"]
            node += ["-p", f"experiment_config:={experiment}", "-p", f"output:={out}"]
            node += ["-p", f"robots:={ROBOTS}", "-p", f"genome_length:={GENOME_LENGTH}"]
            node += ["-p", "graph_timeout:=120.0"]
            return subprocess.run(node, env=env, timeout=timeout).returncode
        finally:
            # The simulator's own Ctrl-C path: it destroys its nodes and leaves.
            simulator.send_signal(signal.SIGINT)
            try:
                simulator.wait(timeout=20)
            except subprocess.TimeoutExpired:
                simulator.kill()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/06_ros2_system"))
    args = parser.parse_args(argv)
    status = evolve(args.out)
    if status != 0:
        return status
    from sdbc_evolution.run.results import read_generations

    log = read_generations(args.out)
    print(f"\nevolved through the graph: {args.out}")
    print("generation  best fitness  mean fitness")
    for generation, best, mean in zip(
        log["generation"], log["best_fitness"], log["mean_fitness"], strict=True
    ):
        print(f"{int(generation):>10}  {best:>12.4f}  {mean:>12.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
