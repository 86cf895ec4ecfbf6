"""A graph's node processes end with their launcher, however it ends, and what dead
DDS processes left in /dev/shm is cleared when a graph starts."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[3]
OWNED = "sdbc_evolution.graph.owned"
GENOME = [0.1] * 108
"""Any genome of gate escape's 11-7-3 network."""


def _children_of(launcher: int) -> list[int]:
    """Pids of the node processes that ``launcher`` started (they run under
    graph/owned.py, which names the launcher's pid first)."""
    pids = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            argv = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if OWNED.encode() in argv:
            at = argv.index(OWNED.encode())
            if argv[at + 1 : at + 2] == [str(launcher).encode()]:
                pids.append(int(proc.name))
    return pids


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has ended; only its parent's wait is missing


def _in_dds(pid: int) -> bool:
    try:
        return "/dev/shm/fastrtps_" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


def _graph_file(tmp_path: Path) -> Path:
    from sdbc_evolution.graph.graph_file import trial_graph

    path = tmp_path / "graph.yaml"
    path.write_text(yaml.safe_dump(trial_graph("gate_escape", GENOME)))
    return path


def _launcher_env(tmp_path: Path) -> dict[str, str]:
    """A launcher's environment: this one's, a ROS home of the test's own, and
    the packages this process imports on the path."""
    return {
        **os.environ,
        "ROS_HOME": str(tmp_path / "ros_home"),
        "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
    }


def test_every_node_ends_when_the_launcher_is_killed(tmp_path):
    env = _launcher_env(tmp_path)
    launcher = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.graph.launch",
            str(_graph_file(tmp_path)),
            "--log-dir",
            str(tmp_path / "logs"),
        ],
        env=env,
        cwd=ROOT,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120.0
        nodes: list[int] = []
        # The simulator and four controllers, each with its DDS participant up
        # (it maps its shared-memory segment).
        while len(nodes) < 5 or not all(_in_dds(p) for p in nodes):
            assert launcher.poll() is None, launcher.communicate()[1]
            assert time.monotonic() < deadline, f"nodes seen: {nodes}"
            time.sleep(0.5)
            nodes = _children_of(launcher.pid)
        time.sleep(2.0)  # into their executors' spin
        launcher.send_signal(signal.SIGKILL)
        launcher.wait()
        deadline = time.monotonic() + 30.0
        while (alive := [p for p in nodes if _alive(p)]) and (
            time.monotonic() < deadline
        ):
            time.sleep(0.2)
        assert alive == [], f"node processes left running: {alive}"
    finally:
        for pid in _children_of(launcher.pid):
            os.kill(pid, signal.SIGKILL)
        if launcher.poll() is None:
            launcher.kill()
            launcher.wait()


def test_a_graph_start_removes_what_killed_dds_processes_left(tmp_path):
    from sdbc_evolution.graph import shm
    from sdbc_evolution.graph.graph_file import load_graph_file
    from sdbc_evolution.graph.processes import ProcessGraph, child_environment

    before = set(os.listdir(shm.SHM_DIR))
    victim = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import rclpy, time\n"
            "from rclpy.node import Node\n"
            "from std_msgs.msg import String\n"
            "rclpy.init()\n"
            "node = Node('victim')\n"
            "node.create_publisher(String, 'victim_topic', 10)\n"
            "print('up', flush=True)\n"
            "time.sleep(600)\n",
        ],
        env={
            **os.environ,
            "ROS_HOME": str(tmp_path / "ros_home"),
            # A domain of its own: no live peer maps the victim's files.
            "ROS_DOMAIN_ID": str(
                (int(os.environ.get("ROS_DOMAIN_ID", "0")) + 100) % 200
            ),
        },
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert victim.stdout is not None and victim.stdout.readline() == "up\n"
        time.sleep(1.0)
    finally:
        victim.kill()
        victim.wait()
    # New files that no process uses: the victim's (other graphs on this machine
    # may be making files of their own meanwhile).
    left = {
        name
        for name in set(os.listdir(shm.SHM_DIR)) - before
        if name.startswith(shm.DDS_FILE_PREFIXES)
    } - shm.dds_files_in_use()
    assert left, "a SIGKILLed DDS process left nothing in /dev/shm to clear"
    time.sleep(shm.STALE_MIN_AGE + 0.5)  # a start leaves the youngest files alone

    env = child_environment()
    env["ROS_HOME"] = str(tmp_path / "ros_home")
    graph = ProcessGraph.from_graph_file(
        load_graph_file(_graph_file(tmp_path)),
        tmp_path,
        log_dir=tmp_path / "logs",
        env=env,
    )
    graph.start()
    try:
        remaining = left & set(os.listdir(shm.SHM_DIR))
    finally:
        codes = graph.stop()
    assert remaining == set()
    # Stopped while still starting up, but by SIGINT, not SIGKILL.
    assert -signal.SIGKILL not in codes.values(), codes


STOP_AT_ONCE = """
import json, sys
from pathlib import Path
from sdbc_evolution.graph.graph_file import load_graph_file
from sdbc_evolution.graph.processes import ProcessGraph, child_environment
folder = Path(sys.argv[1])
graph = ProcessGraph.from_graph_file(
    load_graph_file(folder / "graph.yaml"), folder, log_dir=folder / "logs",
    env=child_environment(),
)
graph.start()
print(json.dumps(graph.stop()))
"""


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_from_background_job(
    argv: list[str], env: dict[str, str]
) -> subprocess.CompletedProcess[str]:
    """Runs ``argv`` to its end with SIGINT ignored, as a non-interactive shell's
    `&` starts it; asserts that it exited with 0."""
    done = subprocess.run(
        argv,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=_ignore_sigint,
    )
    assert done.returncode == 0, done.stderr
    return done


def test_a_graph_started_from_a_background_job_still_stops_by_sigint(tmp_path):
    """A program a non-interactive shell starts with `&` ignores SIGINT, and so
    would the nodes its launcher starts: a stop in their first moments, before
    a node installs its own handler, was lost, and every node SIGKILLed after
    the grace time (seen under `nohup .ci/run &`)."""
    import json

    _graph_file(tmp_path)
    done = _run_from_background_job(
        [sys.executable, "-c", STOP_AT_ONCE, str(tmp_path)], _launcher_env(tmp_path)
    )
    codes = json.loads(done.stdout)
    assert len(codes) == 5
    assert -signal.SIGKILL not in codes.values(), codes


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ignores_sigint_reads_the_process_disposition():
    from sdbc_evolution.graph.processes import ignores_sigint

    # Both set explicitly: this test run may itself ignore SIGINT (a background job).
    for preexec, expected in ((_ignore_sigint, True), (_default_sigint, False)):
        child = subprocess.Popen(
            ["sleep", "30"], preexec_fn=preexec, stdout=subprocess.DEVNULL
        )
        try:
            assert ignores_sigint(child.pid) is expected
        finally:
            child.kill()
            child.wait()


def test_a_node_program_starts_with_sigint_at_its_default_action(tmp_path):
    """Started by the launcher, a program hears SIGINT with its default action
    (the process ends at once) until it installs handlers of its own, even when
    its launcher ignored SIGINT. Python's KeyboardInterrupt, raised inside an
    import, could leave the interpreter's import lock held: a controller stopped
    at a graph's start then hung on its way out until it was SIGKILLed."""
    (tmp_path / "sigint_probe.py").write_text(
        "import signal\n"
        "print(signal.getsignal(signal.SIGINT) is signal.SIG_DFL, flush=True)\n"
    )
    env = _launcher_env(tmp_path)
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env["PYTHONPATH"]])
    done = _run_from_background_job(
        [sys.executable, "-m", OWNED, str(os.getpid()), "1", "sigint_probe"], env
    )
    assert done.stdout == "True\n"


def test_a_node_program_starts_without_the_process_pool_machinery(tmp_path):
    """Watching the launcher takes two constants and a pidfd: a node (one per
    robot in a live graph) does not pay at start for importing what a pool of
    workers needs (multiprocessing, concurrent.futures: about 30 ms)."""
    (tmp_path / "import_probe.py").write_text(
        "import sys\n"
        "print([m for m in ('multiprocessing', 'concurrent.futures') "
        "if m in sys.modules], flush=True)\n"
    )
    env = _launcher_env(tmp_path)
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env["PYTHONPATH"]])
    done = subprocess.run(
        [sys.executable, "-m", OWNED, str(os.getpid()), "1", "import_probe"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.stdout == "[]\n", done.stderr


def test_a_process_killed_after_its_timeout_leaves_its_stacks_in_its_log(tmp_path):
    """A node that does not stop within the shutdown timeout is SIGKILLed, but
    first writes its threads' Python stacks to its log: where it hung."""
    from sdbc_evolution.graph.processes import (
        NodeProcess,
        ProcessGraph,
        child_environment,
    )

    (tmp_path / "deaf_node.py").write_text(
        "import signal, time\n"
        "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
        "print('up', flush=True)\n"
        "def hangs_here():\n"
        "    time.sleep(600)\n"
        "hangs_here()\n"
    )
    env = child_environment()
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env["PYTHONPATH"]])
    logs = tmp_path / "logs"
    graph = ProcessGraph(
        [NodeProcess("deaf", "deaf_node")], shutdown_timeout=1.0, log_dir=logs, env=env
    )
    graph.start()
    log = logs / "deaf.log"
    deadline = time.monotonic() + 60.0
    while "up" not in log.read_text():
        assert time.monotonic() < deadline, log.read_text()
        time.sleep(0.1)
    assert graph.stop() == {"deaf": -signal.SIGKILL}
    text = log.read_text()
    assert "most recent call first" in text and "hangs_here" in text, text
