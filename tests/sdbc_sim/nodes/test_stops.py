"""SIGINT and SIGTERM end every node program cleanly: exit 0, no traceback, no
unretrieved exception, and the evolution node says whether its run is complete."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

START_TIMEOUT = 60.0
NOISE = ("Traceback", "RCLError", "never retrieved", "context is invalid")
PROGRAMS = {
    "simulator": ["sdbc_sim.nodes.simulator_node"],
    "controller": ["sdbc_sim.nodes.controller_node", "--robots", "0", "1"],
    "characteriser": ["sdbc_evolution.nodes.characteriser_node"],
    "recorder": ["sdbc_evolution.nodes.recorder_node", "--topics", "/task_state"],
}
TINY_RUN = (
    "task: gate_escape\ntask_config: {max_steps: 30}\ntreatment: fit\n"
    "generations: GENERATIONS\nseed: 0\n"
    "ga: {population_size: 4, elites: 1, tournament_size: 2}\n"
    "evaluation: {trials: 1, reevaluation_trials: 0}\n"
)


def wait_for_nodes(test_node, process: subprocess.Popen[str], names: set[str]) -> None:
    """Returns once the graph shows nodes ``names`` (their services up)."""
    node, _ = test_node
    deadline = time.monotonic() + START_TIMEOUT
    while not names <= set(node.get_node_names()):
        assert process.poll() is None, process.communicate()[0]
        assert time.monotonic() < deadline, f"{names} did not come up"
        time.sleep(0.1)
    time.sleep(0.5)  # past rclpy's start-up, into the program's own loop


def stop(process: subprocess.Popen[str], signum: int) -> str:
    process.send_signal(signum)
    output = process.communicate(timeout=60)[0]
    assert process.returncode == 0, output
    assert not [n for n in NOISE if n in output], output
    return output


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_a_node_stops_cleanly(name, signum, tmp_path, start_node, test_node):
    module, *args = PROGRAMS[name]
    if name == "recorder":
        args = ["--output", str(tmp_path / "bag"), *args]
    process = start_node(module, *args)
    wait_for_nodes(test_node, process, {name})
    output = stop(process, signum)
    if name == "recorder":
        assert "recorder: bag" in output and "closed" in output
        assert (tmp_path / "bag" / "metadata.yaml").exists()


def test_a_node_says_where_it_is_on_sigusr1(start_node, test_node):
    """SIGUSR1 has a node program write its threads' Python stacks and go on
    (how a hung node says where it hung); SIGINT then still stops it cleanly."""
    process = start_node(*PROGRAMS["simulator"])
    wait_for_nodes(test_node, process, {"simulator"})
    process.send_signal(signal.SIGUSR1)
    time.sleep(1.0)
    assert process.poll() is None
    output = stop(process, signal.SIGINT)
    # faulthandler's stacks: "Current thread 0x... (most recent call first):".
    assert "thread 0x" in output.lower() and "(most recent call first)" in output
    assert "startup.py" in output


def evolution(start_node, tmp_path: Path, generations: int) -> subprocess.Popen[str]:
    config = tmp_path / "run.yaml"
    config.write_text(TINY_RUN.replace("GENERATIONS", str(generations)))
    return start_node(
        "sdbc_evolution.nodes.evolution_node",
        "--ros-args",
        "-p",
        f"experiment_config:={config}",
        "-p",
        f"output:={tmp_path / 'run'}",
        "-p",
        "workers:=1",
        "-p",
        "exit_when_done:=false",
    )


def read_until(process: subprocess.Popen[str], text: str) -> str:
    assert process.stdout is not None
    seen = []
    deadline = time.monotonic() + 5 * START_TIMEOUT
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        assert line, "".join(seen)
        seen.append(line)
        if text in line:
            return "".join(seen)
    raise AssertionError(f"no {text!r} in time:\n{''.join(seen)}")


def stop_a_run(
    start_node, tmp_path: Path, generations: int, after: str, signum: int
) -> str:
    """Starts a run of ``generations``, stops it with ``signum`` once its output
    shows ``after``; returns its output."""
    process = evolution(start_node, tmp_path, generations)
    read_until(process, after)
    return stop(process, signum)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
def test_a_finished_run_stops_saying_it_is_complete(signum, tmp_path, start_node):
    output = stop_a_run(start_node, tmp_path, 2, "run complete", signum)
    assert f"evolution_node: run complete: results in {tmp_path / 'run'}" in output
    assert "interrupted" not in output


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
def test_an_unfinished_run_stops_saying_how_to_resume(signum, tmp_path, start_node):
    output = stop_a_run(start_node, tmp_path, 10_000, "generation 1:", signum)
    assert "evolution_node: interrupted; resume with resume:=true" in output
    assert "run complete" not in output
