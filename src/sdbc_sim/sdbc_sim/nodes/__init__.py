"""The live ROS 2 graph's simulation side: the simulator node (trials in lockstep)
and the controller nodes (one robot's network each). See docs/ros2.md, "The
live ROS 2 graph", for the names of nodes, topics, services and parameters."""
