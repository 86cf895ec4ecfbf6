"""The live graph of a task from a graph file, as ``sdbc-graph`` starts it.

The graph file (``configs/ros/*.yaml``, installed under
``share/sdbc_evolution/config``) is read by the same code as ``sdbc-graph``'s
(:mod:`sdbc_evolution.graph.graph_file`), which gives the same processes: the
simulator, the controllers (``robots_per_process`` per process), with
``graphs: K`` K such graphs in ``graph_0`` ..., the evolution node if the file (or
the ``evolution`` argument) says so, and the recorder when ``record`` names a bag.
As with ``sdbc-graph``, the graph stops when any of its nodes ends (the evolution
node at the end of its run), and Fast DDS files left in /dev/shm by dead processes
are removed first.

    ros2 launch sdbc_evolution graph.launch.py graph_file:=configs/ros/gate_escape.yaml
    ros2 launch sdbc_evolution graph.launch.py namespace:=team_a record:=bags/t7
    ros2 launch sdbc_evolution graph.launch.py --show-args

Arguments left empty keep what the graph file says.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path
from typing import Any

from ament_index_python.packages import get_package_share_directory
from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

ARGUMENTS = {
    "graph_file": (
        str(
            Path(
                get_package_share_directory("sdbc_evolution"),
                "config",
                "gate_escape.yaml",
            )
        ),
        "Graph file (YAML): the task and every node's parameters",
    ),
    "task": ("", "Task of every node (empty: the graph file's)"),
    "task_config": ("", "YAML mapping of task setting overrides (empty: the file's)"),
    "namespace": ("", "Namespace the whole graph is pushed into (empty: none)"),
    "record": ("", "Record the graph's topics to this bag directory (empty: no)"),
    "use_sim_time": ("", "true or false for every node (empty: the file's)"),
    "evolution": ("", "true or false: start the evolution node (empty: the file's)"),
    "experiment_config": (
        "",
        "The evolution node's experiment YAML (empty: the file's)",
    ),
    "output": ("", "The evolution node's results directory (empty: the file's)"),
}
"""Launch arguments: name -> (default, description)."""
BOOLEANS = {"true": True, "false": False}


def _boolean(name: str, text: str) -> bool:
    from sdbc_sim.limits import excerpt

    if text.lower() not in BOOLEANS:
        raise ValueError(
            f"launch argument {name}: expected true or false, got {excerpt(text)}"
        )
    return BOOLEANS[text.lower()]


def _graph(context: LaunchContext) -> list[Any]:
    from sdbc_evolution.graph.graph_file import (
        SHARED_KEY,
        load_graph_file,
        with_parameters,
    )
    from sdbc_evolution.graph.processes import (
        PARAMETERS_FILE,
        graph_processes,
        write_parameters,
    )
    from sdbc_evolution.graph.shm import remove_stale_dds_files
    from sdbc_sim.nodes.interface import EVOLUTION_NODE
    from sdbc_sim.yaml_input import parse_yaml

    given = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    launch = {}
    if given["evolution"]:
        launch["evolution"] = _boolean("evolution", given["evolution"])
    graph_file = load_graph_file(
        given["graph_file"],
        task=given["task"] or None,
        task_config=given["task_config"] or None,
        launch=launch,
    )
    record = Path(given["record"]) if given["record"] else None
    if record is not None and record.exists():
        raise ValueError(
            f"launch argument record: {record} exists already; not overwriting"
        )
    # In the parameters file itself: launch_ros gives a dict of parameters under
    # "/**", which loses to the file's sections that name a node.
    if given["use_sim_time"]:
        graph_file = with_parameters(
            graph_file,
            SHARED_KEY,
            {"use_sim_time": _boolean("use_sim_time", given["use_sim_time"])},
        )
    evolution = {k: given[k] for k in ("experiment_config", "output") if given[k]}
    if evolution:
        graph_file = with_parameters(graph_file, EVOLUTION_NODE, evolution)
    work_dir = Path(tempfile.mkdtemp(prefix="sdbc-launch-"))
    # Removed when ros2 launch exits (its nodes read the file at their start).
    atexit.register(shutil.rmtree, work_dir, ignore_errors=True)
    params_file = work_dir / PARAMETERS_FILE
    write_parameters(graph_file, params_file, given["namespace"])
    remove_stale_dds_files()
    actions: list[Any] = []
    for process in graph_processes(graph_file, params_file, record, given["namespace"]):
        package, executable = process.program
        parameters: list[Any] = [str(params_file)]
        if process.parameters:
            # Only the evolution node's graph_namespaces, which no section sets.
            parameters.append(
                {name: parse_yaml(value, name) for name, value in process.parameters}
            )
        actions.append(
            Node(
                package=package,
                executable=executable,
                namespace="/" + process.namespace if process.namespace else None,
                arguments=list(process.args),
                parameters=parameters,
                remappings=list(process.remaps),
                output="screen",
                # As long as sdbc-graph gives a node to stop after SIGINT (a
                # node waits for its readers' acknowledgements first).
                sigterm_timeout=str(graph_file.settings.shutdown_timeout),
                # A node that ends (the evolution node at the end of its run, or
                # one that fails) ends the graph, as under sdbc-graph.
                on_exit=[EmitEvent(event=Shutdown(reason=f"{process.name} ended"))],
            )
        )
    return actions


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            *(
                DeclareLaunchArgument(name, default_value=default, description=text)
                for name, (default, text) in ARGUMENTS.items()
            ),
            OpaqueFunction(function=_graph),
        ]
    )
