"""The shipped launch files, run with ``ros2 launch`` as a user with a full ROS 2
install runs them: the graph they bring up answers ``run_trial`` as the one
``sdbc-graph`` brings up from the same graph file.

ros2cli, launch and launch_ros are on no package registry, so on a PyPI-only
install these tests are skipped; with them importable (a ROS 2 install, or their
jazzy sources installed into a scratch directory on PYTHONPATH) they run.
"""

from __future__ import annotations

import importlib.util
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(
        importlib.util.find_spec("launch_ros") is None
        or importlib.util.find_spec("ros2launch") is None,
        reason="launch_ros and ros2launch are not importable: they come with a full "
        "ROS 2 install (or its jazzy sources built by hand), not from PyPI",
    ),
]

ROOT = Path(__file__).resolve().parents[3]
ROS2 = "import sys; from ros2cli.cli import main; sys.exit(main())"
"""The ``ros2`` command, run with this interpreter."""
GRAPH_TIMEOUT = 120.0
TRIAL_LINE = re.compile(r"trial seed 7: fitness (\S+), length (\d+), ")


def _env(tmp_path: Path) -> dict[str, str]:
    return {
        **os.environ,
        "ROS_HOME": str(tmp_path / "ros_home"),
        "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
    }


def _ros2(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", ROS2, *args],
        capture_output=True,
        text=True,
        env=_env(tmp_path),
        cwd=tmp_path,
        timeout=GRAPH_TIMEOUT,
    )


def test_the_launch_files_are_installed_with_their_graph_files():
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory("sdbc_evolution"))
    for name in (
        "graph.launch.py",
        "gate_escape.launch.py",
        "evolution.launch.py",
        "gate_escape.launch.xml",
        "gate_escape.launch.yaml",
    ):
        assert (share / "launch" / name).is_file(), name
    for name in ("gate_escape.yaml", "evolution.yaml", "live_experiment.yaml"):
        assert (share / "config" / name).is_file(), name


@pytest.mark.parametrize(
    "launch_file",
    ["gate_escape.launch.py", "gate_escape.launch.xml", "gate_escape.launch.yaml"],
)
def test_each_launch_file_takes_the_graph_arguments(tmp_path, launch_file):
    done = _ros2(tmp_path, "launch", "sdbc_evolution", launch_file, "--show-args")
    assert done.returncode == 0, done.stdout + done.stderr
    for argument in (
        "graph_file",
        "task",
        "namespace",
        "record",
        "use_sim_time",
        "evolution",
    ):
        assert f"'{argument}':" in done.stdout, (argument, done.stdout)


def test_ros2_launch_gate_escape_answers_run_trial_like_sdbc_graph(
    tmp_path, run_graph, client_node
):
    from sdbc_evolution.graph.client import GraphClient
    from sdbc_sim.tasks import make_task

    log = (tmp_path / "launch.log").open("w")
    launch = subprocess.Popen(
        [
            sys.executable,
            "-c",
            ROS2,
            "launch",
            "sdbc_evolution",
            "gate_escape.launch.py",
            "namespace:=launched",
        ],
        env=_env(tmp_path),
        cwd=tmp_path,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    try:
        client = GraphClient(
            client_node,
            make_task("gate_escape"),
            "gate_escape",
            {},
            timeout=GRAPH_TIMEOUT,
            physics="rigid",
            namespace="/launched",
        )
        try:
            client.wait_for_graph(GRAPH_TIMEOUT)
        except Exception as error:
            raise AssertionError(
                f"{error}\n{(tmp_path / 'launch.log').read_text()[-4000:]}"
            ) from None
        launched = client.run_trial(7)
        # sdbc-graph beside it, on the graph file the launch file installs.
        done = run_graph(
            str(ROOT / "configs" / "ros" / "gate_escape.yaml"),
            "--namespace",
            "graphed",
            "--trial",
            "7",
        )
    finally:
        os.killpg(launch.pid, signal.SIGINT)
        try:
            launch.wait(60)
        except subprocess.TimeoutExpired:
            os.killpg(launch.pid, signal.SIGKILL)
            launch.wait()
        log.close()
    assert done.returncode == 0, done.stderr
    fitness, length = TRIAL_LINE.search(done.stdout).groups()
    assert launched.length == int(length)
    assert launched.fitness == pytest.approx(float(fitness), abs=1e-5)
    # ros2 launch stopped every node it started on Ctrl-C.
    output = (tmp_path / "launch.log").read_text()
    started = re.findall(r"process started with pid \[(\d+)\]", output)
    assert len(started) == 5, output[-3000:]
    time.sleep(1.0)
    assert not [pid for pid in started if Path(f"/proc/{pid}").exists()], output


def test_ros2_launch_evolution_runs_an_experiment_to_its_end(tmp_path):
    import yaml
    from sdbc_evolution.run.results import read_generations

    experiment = tmp_path / "tiny.yaml"
    experiment.write_text(
        yaml.safe_dump(
            {
                "treatment": "ns-sd+",
                "generations": 2,
                "seed": 1,
                "ga": {"population_size": 4, "elites": 1, "tournament_size": 2},
                "novelty": {"k": 2},
                "evaluation": {"trials": 1, "reevaluation_trials": 0},
            }
        )
    )
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            ROS2,
            "launch",
            "sdbc_evolution",
            "evolution.launch.py",
            f"experiment_config:={experiment}",
            f"output:={tmp_path / 'run'}",
            "namespace:=evolved",
            "task_config:={max_steps: 40}",
            "use_sim_time:=true",
        ],
        capture_output=True,
        text=True,
        env=_env(tmp_path),
        cwd=tmp_path,
        timeout=600,
    )
    # The evolution node ends the launch when its run is complete.
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "run complete" in done.stdout + done.stderr
    assert read_generations(tmp_path / "run")["generation"].tolist() == [0.0, 1.0]
