"""An outside simulator answering fitness 20 (the contract says [0, 1]) stops the
evolution node's live run with one line naming the value, at the first trial the
node runs to learn the task, before the run directory exists: the check every
evaluator's answers pass (docs/limits.md)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros

HERE = Path(__file__).resolve().parents[3] / "examples" / "06_ros2_system"


def test_an_outside_simulator_answering_fitness_20_stops_the_run(
    tmp_path: Path, ros_home: Path
) -> None:
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(Path(__file__).parent))
    from point_chase_simulator import GENOME_LENGTH, ROBOTS, stop
    from test_outside_simulator import EXPERIMENT, RUN_TIMEOUT

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(yaml.safe_dump({**EXPERIMENT, "generations": 2}))
    out = tmp_path / "run"
    simulator = subprocess.Popen(
        [sys.executable, str(HERE / "point_chase_simulator.py"), "--fitness", "20"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    parameters = {
        "task": "point_chase",
        "experiment_config": experiment,
        "output": out,
        "evaluator": "live",
        "robots": ROBOTS,
        "genome_length": GENOME_LENGTH,
        "graph_timeout": 120.0,
    }
    argv = [sys.executable, "-m", "sdbc_evolution.nodes.evolution_node", "--ros-args"]
    for name, value in parameters.items():
        argv += ["-p", f"{name}:={value}"]
    try:
        done = subprocess.run(
            argv, env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT
        )
    finally:
        stop(simulator)
    assert done.returncode == 1, done.stderr
    failed = [line for line in done.stderr.splitlines() if "run failed" in line]
    assert len(failed) == 1, done.stderr
    assert (
        "TaskFailed: a first trial: task 'point_chase' returned trial fitness 20.0 at "
        "genome 0, trial 0" in failed[0]
    )
    assert "the contract says in [0, 1]" in failed[0]
    assert not out.exists()
