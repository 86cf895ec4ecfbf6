"""Evolution through the live graph, as ``sdbc-graph configs/ros/evolution.yaml``
runs it: the simulator, four controllers and the evolution node, which runs the
small experiment of ``live_experiment.yaml`` (installed beside the graph file) and
ends the graph when the run is complete.

    ros2 launch sdbc_evolution evolution.launch.py output:=results/live
    ros2 launch sdbc_evolution evolution.launch.py record:=bags/evolution
    ros2 topic echo /generation_stats   # volatile: echo before the run starts

Every argument of graph.launch.py applies (``--show-args``).
"""

from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration

SHARE = Path(get_package_share_directory("sdbc_evolution"))


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            # The graph file names its experiment relative to the repository;
            # installed, the experiment lies beside it.
            DeclareLaunchArgument(
                "experiment_config",
                default_value=str(SHARE / "config" / "live_experiment.yaml"),
                description="The evolution node's experiment YAML",
            ),
            IncludeLaunchDescription(
                PythonLaunchDescriptionSource(
                    str(SHARE / "launch" / "graph.launch.py")
                ),
                launch_arguments={
                    "graph_file": str(SHARE / "config" / "evolution.yaml"),
                    "experiment_config": LaunchConfiguration("experiment_config"),
                }.items(),
            ),
        ]
    )
