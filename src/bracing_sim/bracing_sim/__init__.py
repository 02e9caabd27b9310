"""Bracing manipulator simulator: pure numerical core (``bracing_sim.core``) and its ROS 2 node."""
