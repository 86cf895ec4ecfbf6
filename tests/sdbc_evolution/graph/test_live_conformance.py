"""``sdbc-conformance --live`` against a real outside simulator (tutorial 06's,
written against the contract alone): it passes as it is, and each way of
breaking the contract that a live run would meet (a fitness of 20, a
characterisation value of 19, a group of the wrong size, a group more in some
messages, a step missing) fails one check with one line naming the problem.
This project's own graph (``sdbc-graph``) passes too."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[3]
HERE = ROOT / "examples" / "06_ros2_system"
CHECK_TIMEOUT = 600.0
"""Seconds the checks may take on a loaded two-core machine."""


def conformance(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    return subprocess.run(
        [sys.executable, "-m", "sdbc_evolution.conformance", "--live", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=CHECK_TIMEOUT,
    )


def check_the_simulator(*faults: str) -> subprocess.CompletedProcess[str]:
    """The live checks of the point chase simulator started with ``faults``."""
    sys.path.insert(0, str(HERE))
    from point_chase_simulator import GENOME_LENGTH, ROBOTS, stop

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    simulator = subprocess.Popen(
        [sys.executable, str(HERE / "point_chase_simulator.py"), *faults],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        return conformance(
            "point_chase",
            "--robots",
            str(ROBOTS),
            "--genome-length",
            str(GENOME_LENGTH),
        )
    finally:
        stop(simulator)


def test_the_outside_simulator_keeps_to_the_contract(ros_home: Path) -> None:
    done = check_the_simulator()
    assert done.returncode == 0, done.stdout + done.stderr
    assert "4/4 checks passed for point_chase" in done.stdout
    assert "4 trials of 25-25 steps" in done.stdout, done.stdout


@pytest.mark.parametrize(
    ("faults", "check", "problem"),
    [
        (
            ["--fitness", "20"],
            "ranges",
            "genome 0, seed 0: fitness is 20.0, the contract says in [0, 1]",
        ),
        (
            ["--characterisation", "19"],
            "ranges",
            "genome 0, seed 0: characterisation value 0 ('mean x') is 19.0, the "
            "contract says in [0, 1]",
        ),
        (
            ["--chasers", "3"],
            "trials",
            "step 1, group 'Chaser': 3 entities, outside its limits [2, 2]",
        ),
        (
            ["--extra-group-from", "5"],
            "trials",
            "step 5: 3 groups in the message, 2 in the description",
        ),
        (["--skip-step", "5"], "trials", "step 6 arrived after step 4"),
    ],
    ids=["fitness-20", "characterisation-19", "group-size", "group-count", "gap"],
)
def test_each_broken_contract_fails_one_check_naming_the_problem(
    ros_home: Path, faults: list[str], check: str, problem: str
) -> None:
    done = check_the_simulator(*faults)
    assert done.returncode == 1, done.stdout + done.stderr
    failed = [line for line in done.stdout.splitlines() if line.startswith("FAIL")]
    assert failed, done.stdout
    assert failed[0].split()[1] == check, done.stdout
    assert problem in failed[0], done.stdout
    assert failed[0].count("\n") == 0 and len(failed[0]) < 400, failed[0]
    # The checks after it need what it checks: said, not run.
    for line in failed[1:]:
        assert f"not run: the {check} check failed" in line, done.stdout


def test_another_systems_task_needs_its_sizes(ros_home: Path) -> None:
    done = conformance("point_chase")
    assert done.returncode == 2, done.stdout + done.stderr
    assert done.stderr.strip() == (
        "sdbc-conformance: error: task 'point_chase' is not one of this project's: "
        "give its --robots and --genome-length"
    )


def test_this_projects_graph_keeps_to_the_contract(
    tmp_path: Path, ros_home: Path
) -> None:
    graph = tmp_path / "graph.yaml"
    graph.write_text(
        (ROOT / "configs" / "ros" / "gate_escape.yaml")
        .read_text()
        .replace('task_config: "{}"', 'task_config: "{max_steps: 60}"')
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    said = tmp_path / "launcher.txt"
    launcher = subprocess.Popen(
        [sys.executable, "-m", "sdbc_evolution.graph.launch", str(graph)]
        + ["--log-dir", str(tmp_path / "logs")],
        env=env,
        stdout=said.open("w"),
        stderr=subprocess.STDOUT,
    )
    try:
        done = conformance(
            "gate_escape", "--task-config", "{max_steps: 60}", "--graph-timeout", "300"
        )
    finally:
        launcher.send_signal(signal.SIGINT)
        try:
            launcher.wait(timeout=120)
        except subprocess.TimeoutExpired:
            launcher.kill()
            launcher.wait()
    assert done.returncode == 0, done.stdout + done.stderr + said.read_text()
    assert "4/4 checks passed for gate_escape" in done.stdout
    assert "4 trials of 60-60 steps" in done.stdout, done.stdout
    assert "4 characterisation values each" in done.stdout, done.stdout
