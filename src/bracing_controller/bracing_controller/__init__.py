"""The controller node: the decoupled force/position law of bracing_core, answering over ROS 2."""
