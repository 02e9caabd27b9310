"""command_output effort_forward: the controller drives a ros2_control robot.

The torque law's efforts go out as std_msgs/Float64MultiArray on ``effort_command_topic``, one value
per joint in the order of ``effort_command_joints`` (a JointGroupEffortController's ``joints``), on a
timer at ``control_rate`` on the node's clock (``use_sim_time``: /clock), computed from the latest
``joint_states`` of any publisher (joint_state_broadcaster's, or our simulator's). A state with a joint
missing or not finite is refused, with a rate-limited warning, and nothing is sent from it.

``state_timeout`` (0: off): no command from a state that arrived longer ago than that on the node's
clock; zero efforts go out instead, every tick, until a state is answered again (warned once when
the state goes stale, said when it resumes). Zero, not silence: the forward controller
(forward_controllers_base.cpp) writes the last command it took on every update, with no timeout,
so silence would hold efforts computed from a state nobody sees any more; zero is what a
JointGroupEffortController commands when it stops (its on_deactivate). The policy, and why, is
``bracing_core.state_freshness``.

/clock: checked before it sets the node's clock (``bracing_ros.sim_clock``). A negative or malformed
one is refused; a jump back is a reset (ROS time-jump semantics): rcl restarts the timer from the new
time (its next tick one period after it), and the state held from before the jump is stale at once
(with ``state_timeout`` on: zeros until the next state); a jump ahead fires the timer once (rcl skips
the periods jumped over) and, with ``state_timeout`` on, makes the held state stale too.
"""

from __future__ import annotations

import numpy as np
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from bracing_core.controller_config import ControllerConfig
from bracing_core.node_log import NodeLog
from bracing_core.state_freshness import StateFreshness
from bracing_core.types import Vector
from bracing_ros.qos import COMMAND_QOS


class EffortForward:
    """The effort publisher, the latest joint_states (and when it came), and the order the efforts go out in."""

    def __init__(self, node: Node, config: ControllerConfig, names: list[str], log: NodeLog) -> None:
        """``names``: the law's (model) joint order."""
        joints = list(config.effort_command_joints) or list(config.shared.joint_names)
        self.order = np.array([names.index(j) for j in joints], dtype=int)
        self.joints = joints
        self.publisher = node.create_publisher(Float64MultiArray, config.effort_command_topic, COMMAND_QOS)
        self.clock = node.get_clock()
        self.freshness = StateFreshness(config.state_timeout, log)
        self.latest: bytes | None = None
        self.zeros = Float64MultiArray(data=[0.0] * len(joints))

    def now_ns(self) -> int:
        """The node's clock [ns] (use_sim_time: the last /clock taken)."""
        return int(self.clock.now().nanoseconds)

    def on_state(self, data: bytes) -> None:
        self.latest = data
        if self.freshness.enabled:
            self.freshness.received(self.now_ns())

    def send(self, command: Vector) -> None:
        """The law's efforts (model order) as the forward controller takes them."""
        self.publisher.publish(Float64MultiArray(data=[float(v) for v in np.asarray(command)[self.order]]))
        self.freshness.answered()

    def send_zeros(self) -> None:
        """Zero efforts: the state is stale (``state_timeout``)."""
        self.publisher.publish(self.zeros)
