"""The live ROS 2 graph's evolution side: the evolution node (an experiment,
optionally evaluated through the live graph) and the recorder (rosbag2 bags).
See docs/ros2.md, "The live ROS 2 graph"."""
