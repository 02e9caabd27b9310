"""The simulator node: the constrained robot + motor model of bracing_core, stepped over ROS 2."""
