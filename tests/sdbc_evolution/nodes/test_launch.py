"""The graph launcher: graph files, the processes they make, and the clean-up of
what killed DDS processes leave in /dev/shm."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from sdbc_evolution.graph import shm
from sdbc_evolution.graph.graph_file import GraphError, load_graph_file
from sdbc_evolution.graph.processes import graph_processes

# Graph files name nodes' parameters; reading them needs the ROS 2 workspace.
pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[3]


def write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "graph.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def minimal(**launch_settings) -> dict:
    return {
        "sdbc_graph": {"ros__parameters": launch_settings},
        "/**": {
            "ros__parameters": {"task": "gate_escape", "task_config": {"max_steps": 50}}
        },
    }


def test_the_shipped_graph_files_load():
    for path in sorted((ROOT / "configs" / "ros").glob("*.yaml")):
        if "sdbc_graph" not in yaml.safe_load(path.read_text()):
            continue  # an experiment configuration, not a graph file
        graph = load_graph_file(path)
        assert graph.task in {"gate_escape", "resource_sharing", "predator_prey"}


def test_task_config_becomes_one_string_parameter_for_every_node(tmp_path):
    graph = load_graph_file(write(tmp_path, minimal()))
    assert graph.task == "gate_escape" and graph.task_config == {"max_steps": 50}
    shared = graph.parameters["/**"]["ros__parameters"]
    assert shared["task_config"] == "{max_steps: 50}"
    assert "sdbc_graph" not in graph.parameters


def test_one_process_per_robot_by_default_or_several_robots_per_process(tmp_path):
    graph = load_graph_file(write(tmp_path, minimal()))
    names = [p.name for p in graph_processes(graph, tmp_path / "p.yaml")]
    assert names == [
        "simulator",
        "controller 0",
        "controller 1",
        "controller 2",
        "controller 3",
    ]
    graph = load_graph_file(
        write(tmp_path, minimal(robots_per_process=3, evolution=True))
    )
    processes = graph_processes(graph, tmp_path / "p.yaml", record=tmp_path / "bag")
    assert [p.name for p in processes] == [
        "simulator",
        "controller 0-2",
        "controller 3",
        "evolution",
        "recorder",
    ]
    controllers = processes[1].argv
    assert controllers[
        controllers.index("--robots") + 1 : controllers.index("--ros-args")
    ] == (
        "0",
        "1",
        "2",
    )
    recorder = processes[-1].argv
    for topic in (
        "/task_state",
        "/robot_3/command",
        "/robot_0/sensors",
        "/best_genome",
    ):
        assert topic in recorder
    for process in processes:
        assert process.argv[-2:] == ("--params-file", str(tmp_path / "p.yaml"))


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (
            {
                "sdbc_graph": {"ros__parameters": {"robots": 2}},
                "/**": {"ros__parameters": {"task": "x"}},
            },
            "robots",
        ),
        ({"/**": {"ros__parameters": {}}}, "name the task"),
        (
            {"/**": {"ros__parameters": {"task": "gate_escape"}}, "simulator": {}},
            "simulator",
        ),
        (
            {
                "/**": {
                    "ros__parameters": {"task": "gate_escape", "task_config": "[1, 2]"}
                }
            },
            "task_config",
        ),
        (minimal(robots_per_process=0), "robots_per_process"),
        (minimal(shutdown_timeout=-1), "shutdown_timeout"),
        ({**minimal(), "sdbc_graph": {"evolution": True}}, "sdbc_graph"),
    ],
)
def test_malformed_graph_files_are_refused_naming_the_problem(tmp_path, data, message):
    with pytest.raises(GraphError, match=message):
        load_graph_file(write(tmp_path, data))


def test_an_unknown_task_or_setting_is_refused_before_any_process_starts(tmp_path):
    data = minimal()
    data["/**"]["ros__parameters"]["task_config"] = {"max_stepz": 3}
    graph = load_graph_file(write(tmp_path, data))
    with pytest.raises(GraphError, match="max_stepz"):
        graph_processes(graph, tmp_path / "p.yaml")


def test_the_command_line_refuses_bad_input_with_status_2(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    no_genome = write(tmp_path, minimal())
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.graph.launch",
            str(no_genome),
            "--trial",
            "1",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert result.returncode == 2
    assert "genome" in result.stderr
    (tmp_path / "bag").mkdir()
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.graph.launch",
            str(ROOT / "configs" / "ros" / "gate_escape.yaml"),
            "--record",
            str(tmp_path / "bag"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert result.returncode == 2
    assert "exists" in result.stderr


def test_orphaned_dds_files_are_removed_and_files_in_use_are_kept(
    tmp_path, monkeypatch
):
    monkeypatch.setattr(shm, "SHM_DIR", tmp_path)
    orphan = tmp_path / "fastrtps_0123456789abcdef"
    orphan_lock = tmp_path / "fastrtps_0123456789abcdef_el"
    semaphore = tmp_path / "sem.fastrtps_port7411_mutex"
    in_use = tmp_path / "fastrtps_port7413"
    other = tmp_path / "not_dds"
    for path in (orphan, orphan_lock, semaphore, in_use, other):
        path.write_bytes(b"\0" * 16)
    # A running process (this one) holds one of them open.
    with in_use.open("rb"):
        removed = shm.remove_orphaned_dds_files(since=0.0)
    assert sorted(removed) == sorted(p.name for p in (orphan, orphan_lock, semaphore))
    assert in_use.exists() and other.exists()
    assert not orphan.exists()


def test_dds_files_older_than_the_graph_are_left_alone(tmp_path, monkeypatch):
    monkeypatch.setattr(shm, "SHM_DIR", tmp_path)
    old = tmp_path / "fastrtps_feedfacefeedface"
    old.write_bytes(b"")
    assert shm.remove_orphaned_dds_files(since=old.stat().st_ctime + 60.0) == []
    assert old.exists()


@pytest.mark.parametrize(
    ("launch", "message"),
    [
        ({"robots_per_process": 1.5}, "sdbc_graph.robots_per_process: .* integer"),
        ({"evolution": "yes"}, "sdbc_graph.evolution: .* valid boolean, got 'yes'"),
        ({"shutdown_timeout": float("nan")}, "sdbc_graph.shutdown_timeout: .* finite"),
        ({"trial_timeout": "60"}, "sdbc_graph.trial_timeout: .* valid number"),
        ({"record_topics": ["/a", ""]}, r"sdbc_graph.record_topics.1: "),
        ({"robots": 2}, r"sdbc_graph.robots: unknown key; known keys: \["),
    ],
)
def test_launcher_settings_are_checked_like_every_other_setting(
    tmp_path, launch, message
):
    data = {**minimal(), "sdbc_graph": {"ros__parameters": launch}}
    with pytest.raises(GraphError, match=message):
        load_graph_file(write(tmp_path, data))
