"""Gate escape's live graph, as ``sdbc-graph configs/ros/gate_escape.yaml`` starts it:
the simulator and four controllers (one process each) with the example genome.

    ros2 launch sdbc_evolution gate_escape.launch.py
    ros2 launch sdbc_evolution gate_escape.launch.py namespace:=team_a record:=bags/t7
    ros2 service call /run_trial sdbc_msgs/srv/RunTrial "{seed: 7}"

Every argument of graph.launch.py applies (``--show-args``).
"""

from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource

SHARE = Path(get_package_share_directory("sdbc_evolution"))


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            IncludeLaunchDescription(
                PythonLaunchDescriptionSource(
                    str(SHARE / "launch" / "graph.launch.py")
                ),
                launch_arguments={
                    "graph_file": str(SHARE / "config" / "gate_escape.yaml")
                }.items(),
            )
        ]
    )
