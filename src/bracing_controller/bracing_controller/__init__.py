"""The paper's decoupled force/position controller: pure law (``law``), trajectories, and its ROS 2 node."""
