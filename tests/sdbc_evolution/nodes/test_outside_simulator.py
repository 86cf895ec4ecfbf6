"""Evolution through another system's simulator: the evolution node drives a
minimal simulator written against the contract alone (not sdbc_sim's; tutorial
examples/06_ros2_system),
learns the task from its messages, and the same run gives the same result twice."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.ros

HERE = Path(__file__).resolve().parents[3] / "examples" / "06_ros2_system"
EXPERIMENT = {
    "task": "point_chase",
    "treatment": "ns-sd+",
    "generations": 3,
    "seed": 5,
    "ga": {"population_size": 4, "elites": 1, "tournament_size": 2},
    "novelty": {"k": 2},
    "evaluation": {"trials": 2, "reevaluation_trials": 0},
}
RUN_TIMEOUT = 600.0
"""Seconds a run may take on a loaded two-core machine."""


def evolve_through_the_outside_simulator(tmp_path: Path, name: str) -> Path:
    sys.path.insert(0, str(HERE))
    from point_chase_simulator import GENOME_LENGTH, ROBOTS, stop

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(yaml.safe_dump(EXPERIMENT))
    out = tmp_path / name
    log = (tmp_path / f"{name}-simulator.log").open("w")
    simulator = subprocess.Popen(
        [sys.executable, str(HERE / "point_chase_simulator.py")],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    try:
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "sdbc_evolution.nodes.evolution_node",
                "--ros-args",
                "-p",
                "task:=point_chase",
                "-p",
                f"experiment_config:={experiment}",
                "-p",
                f"output:={out}",
                "-p",
                "evaluator:=live",
                "-p",
                f"robots:={ROBOTS}",
                "-p",
                f"genome_length:={GENOME_LENGTH}",
                "-p",
                "graph_timeout:=120.0",
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=RUN_TIMEOUT,
        )
    finally:
        stop(simulator)
        log.close()
    assert done.returncode == 0, (
        done.stderr + (tmp_path / f"{name}-simulator.log").read_text()
    )
    assert "learnt from a first trial" in done.stderr
    return out


def test_evolution_through_an_outside_simulator_twice(tmp_path, ros_home) -> None:
    from sdbc_evolution.run.results import (
        TIME_COLUMNS,
        read_generations,
        read_individuals,
    )

    runs = [evolve_through_the_outside_simulator(tmp_path, n) for n in ("a", "b")]
    generations = [read_generations(run) for run in runs]
    assert len(generations[0]["generation"]) == EXPERIMENT["generations"]
    # The SDBC's names came from the messages: chasers and a target.
    header = (runs[0] / "generations.csv").read_text().splitlines()[0]
    assert "Chaser-target distance (M)" in header
    assert "Chaser dispersion (F)" in header
    for column, values in generations[0].items():
        if column not in TIME_COLUMNS:
            np.testing.assert_array_equal(values, generations[1][column], column)
    best = [np.load(run / "best_genomes.npy") for run in runs]
    assert best[0].shape == (EXPERIMENT["generations"], 6)
    np.testing.assert_array_equal(best[0], best[1])
    # Every individual of every generation too, SDBC vectors included.
    individuals = [read_individuals(run) for run in runs]
    assert individuals[0].keys() == individuals[1].keys()
    for key, values in individuals[0].items():
        np.testing.assert_array_equal(values, individuals[1][key], key)


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        (
            ["evaluator:=local", "robots:=2", "genome_length:=6"],
            "it can only be evaluated live",
        ),
        (["evaluator:=live", "robots:=2"], "robots and genome_length must be set"),
    ],
    ids=["not-live", "no-genome-length"],
)
def test_another_systems_task_needs_live_robots_and_genome_length(
    ros_home, parameters: list[str], message: str
) -> None:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    argv = [sys.executable, "-m", "sdbc_evolution.nodes.evolution_node"]
    argv += ["--ros-args", "-p", "task:=point_chase", "-p", "generations:=2"]
    for parameter in parameters:
        argv += ["-p", parameter]
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "task 'point_chase' is not one of this project's" in done.stderr
    assert message in done.stderr
