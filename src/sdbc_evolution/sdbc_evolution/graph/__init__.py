"""The live ROS 2 graph: launcher, trial client, live evaluator and bags."""
