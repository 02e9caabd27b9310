"""bracing-controller: answers every joint_states with a motor_command (eq. 41 or 38).

Thin: ROS parameters -> ControllerConfig -> DecoupledController; the command is
stamped with the state it answers, which is what the simulator's lockstep waits for.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from geometry_msgs.msg import Point
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState

from bracing_controller.config import ControllerConfig
from bracing_controller.law import ControlOutput, DecoupledController
from bracing_msgs.msg import ControllerState, MotorCommand
from bracing_sim.commands import MODE_CODES
from bracing_sim.core.types import Vector
from bracing_sim.ros_common import (
    STREAM_QOS,
    SUBSCRIBE_QOS,
    RateLimitedLog,
    SubscriptionWaiter,
    nanoseconds,
    read_parameters,
    run,
)


class StateError(ValueError):
    """A joint_states message the controller cannot use."""


def joint_vectors(msg: JointState, joint_names: list[str]) -> tuple[Vector, Vector]:
    """(q, dq) in ``joint_names`` order from a JointState matched by name."""
    names = list(msg.name)
    if len(msg.position) != len(names) or len(msg.velocity) != len(names):
        raise StateError(f"{len(names)} names, {len(msg.position)} positions, {len(msg.velocity)} velocities")
    if len(set(names)) != len(names):
        raise StateError("duplicate joint names")
    index = {name: k for k, name in enumerate(names)}
    missing = [j for j in joint_names if j not in index]
    if missing:
        raise StateError(f"missing joints {missing}")
    order = [index[j] for j in joint_names]
    q = np.asarray(msg.position, dtype=float)[order]
    dq = np.asarray(msg.velocity, dtype=float)[order]
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq))):
        raise StateError("non-finite position or velocity")
    return q, dq


def _point(v: Vector) -> Point:
    return Point(x=float(v[0]), y=float(v[1]), z=float(v[2]))


class ControllerNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_controller", **kwargs)  # type: ignore[arg-type]
        self.config = ControllerConfig.from_params(read_parameters(self))
        self.law = DecoupledController(self.config)
        self.joint_names = list(self.law.plant.joint_names)
        self.mode_code = MODE_CODES[self.config.shared.input_mode]
        self.contact_names = [c.name for c in self.config.shared.contacts]
        self.command_pub = self.create_publisher(MotorCommand, "motor_command", STREAM_QOS)
        self.state_pub = self.create_publisher(ControllerState, "controller_state", STREAM_QOS)
        self.state_sub = self.create_subscription(JointState, "joint_states", self._on_state, SUBSCRIBE_QOS)
        self.report = RateLimitedLog(self)
        self.get_logger().info(
            f"{self.config.shared.input_mode.value} output, contacts {self.contact_names or 'none'}, "
            f"task dimension {self.config.task_dimension}"
        )

    def _on_state(self, msg: JointState) -> None:
        try:
            q, dq = joint_vectors(msg, self.joint_names)
        except StateError as exc:
            self.report("error", str(exc).split(" ")[0], f"joint_states ignored: {exc}")
            return
        t = nanoseconds(msg.header.stamp) * 1e-9
        start = time.perf_counter()
        out = self.law.update(t, q, dq)
        compute_time = time.perf_counter() - start
        if not np.all(np.isfinite(out.command)):
            self.report("error", "command", f"non-finite command at t = {t:.6f} s: not sent")
            return
        if out.damped:
            self.report("warning", "damped", "B is near-singular: using a damped inverse")
        command = MotorCommand(mode=self.mode_code, name=self.joint_names, value=out.command.tolist())
        command.header.stamp = msg.header.stamp
        self.command_pub.publish(command)
        self.state_pub.publish(self._state_message(msg, out, compute_time))

    def _state_message(self, msg: JointState, out: ControlOutput, compute_time: float) -> ControllerState:
        state = ControllerState()
        state.header.stamp = msg.header.stamp
        state.header.frame_id = "world"
        state.hand_desired = _point(out.hand_desired)
        state.hand_actual = _point(out.hand_actual)
        state.contact_name = self.contact_names
        state.desired_normal_force = out.desired_normal_force.tolist()
        state.brace_desired = [_point(p) for p in out.brace_desired]
        state.brace_actual = [_point(p) for p in out.brace_actual]
        state.command = out.command.tolist()
        state.compute_time = compute_time
        return state


def spin(node: ControllerNode) -> int:
    """Answer states as they come (a wait set on joint_states), serving the executor in between."""
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    waiter = SubscriptionWaiter(node, node.state_sub)
    answered = 0
    try:
        if node.config.wait_for_recorder:
            # A recorder that discovers these publishers late may miss the first answers if this
            # process is stopped soon after (a short run): be matched before answering. States
            # that arrive meanwhile wait in the subscription's queue.
            since, told = time.monotonic(), False
            while node.command_pub.get_subscription_count() < 2 or node.state_pub.get_subscription_count() < 1:
                executor.spin_once(timeout_sec=0.05)
                if not told and time.monotonic() - since > 2.0:
                    told = True
                    node.get_logger().info("waiting for the recorder to subscribe to the command and state topics")
        while True:
            messages = waiter.take(0.1)
            for msg in messages:
                node._on_state(msg)
            answered += len(messages)
            if not messages or answered >= 100:
                answered = 0
                executor.spin_once(timeout_sec=0.0)  # parameter services and the like
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0


def main(args: list[str] | None = None) -> int:
    sys.exit(run(ControllerNode, spin, args))  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
