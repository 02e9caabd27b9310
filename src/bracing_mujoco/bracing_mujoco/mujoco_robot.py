"""bracing-mujoco-robot: the scenario's robot in MuJoCo, with a mujoco_ros2_control robot's topic face.

As a mujoco_ros2_control robot running a ``JointGroupEffortController`` named ``effort_controller``,
a ``joint_state_broadcaster`` and a ``force_torque_sensor_broadcaster`` per contact: it subscribes
``effort_controller/commands`` (std_msgs/Float64MultiArray, one effort per joint of robot.joint_names
in that order; a message larger than max_message_elements or max_name_length, a wrong length or a
non-finite value is refused with a rate-limited error and the held command kept) and publishes
``joint_states``, ``/clock`` and ``contact_wrench/<contact>`` (geometry_msgs/WrenchStamped, frame
``world``: MuJoCo's contact force on the robot at the contact sphere, or on its link's shapes with
robot.collision_geometry and ``point: geometry``), and ``robot_description``
(latched) for the recorder's /tf. Node name and parameters are the
simulator's (``bracing_simulator``: robot, contacts, gravity, step, duration), so bracing-pair follows
it on run_status as it follows our simulator (``bracing-pair --engine mujoco``).

Stepping: MuJoCo at ``step`` with the latest command held. Like mujoco_ros2_control's loop (read, the
controllers' update, write, mj_step in one thread) each state waits for the controller's answer, here
over DDS: a step is taken once a command has come since the state before it, or after
``EFFORT_WAIT_S`` of wall time without one (then with the held command), so a slow machine slows the
run down instead of starving the controller. That policy is ROS-free: ``bracing_core.stepping.HeldEffort``.
With ``use_sim_time`` it follows its own /clock, each message checked first (``bracing_ros.sim_clock``).
"""

from __future__ import annotations

import sys
import time
from functools import partial

from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from bracing_core import schema
from bracing_core.config import SimulatorConfig
from bracing_core.message_limits import MessageLimits, SizeError
from bracing_core.stepping import PROGRESS_PERIOD_S, HeldEffort, Periodic
from bracing_msgs.msg import RunStatus
from bracing_mujoco.mujoco_plant import MujocoRobot
from bracing_ros import parameters, report_encoders, wire
from bracing_ros.ack_window import AckWindow
from bracing_ros.matching import create_waking_publisher, wait_until
from bracing_ros.node_log import RosNodeLog
from bracing_ros.node_main import run
from bracing_ros.qos import COMMAND_QOS, DESCRIPTION_QOS, STREAM_QOS
from bracing_ros.raw_messages import read_checked
from bracing_ros.sim_clock import guard_clock
from bracing_ros.status import StatusPublisher
from bracing_ros.stop_signal import StoppableExecutor

COMMAND_TOPIC = "effort_controller/commands"
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"


class MujocoRobotNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_simulator", **kwargs)  # type: ignore[arg-type]
        values = schema.read("simulator", parameters.given_parameters(self))
        self.config = SimulatorConfig.from_values(values)
        parameters.declare(self, "simulator", values)
        self.robot = MujocoRobot.build(self.config)
        self.joint_names = self.robot.joint_names
        self.step_ns = round(self.config.step * 1e9)
        self.total_steps = round(self.config.duration / self.config.step) if self.config.duration > 0 else None
        self.steps = 0
        publisher = partial(create_waking_publisher, self)
        self.joint_pub = publisher(JointState, "joint_states", STREAM_QOS)
        self.clock_pub = publisher(Clock, "/clock", STREAM_QOS)
        self.wrench_pubs = [publisher(WrenchStamped, f"contact_wrench/{c}", STREAM_QOS) for c in self.robot.contacts]
        self.description_pub = publisher(String, "robot_description", DESCRIPTION_QOS)
        self.description_pub.publish(String(data=self.robot.description))
        self.publishers_ = [self.joint_pub, self.clock_pub, *self.wrench_pubs, self.description_pub]
        self.flow = AckWindow(self, self.publishers_, STREAM_QOS.depth)
        self.joint_wire = wire.JointStateEncoder(self.joint_names)
        self.clock_wire = report_encoders.ClockEncoder()
        self.wrench_wire = report_encoders.WrenchStampedEncoder("world")
        # Raw: a message's sizes are checked before its elements are decoded.
        self.limits = MessageLimits.of(self.config)
        self.command_sub = self.create_subscription(
            Float64MultiArray, COMMAND_TOPIC, self.on_command, COMMAND_QOS, raw=True
        )
        self.status = StatusPublisher(self)
        self.log = RosNodeLog(self, self.status, self.config.log_throttle_period)
        guard_clock(self, self.log)  # use_sim_time (its own /clock): a bad one refused, not fatal
        self.held = HeldEffort(self.joint_names, COMMAND_TOPIC, self.log)
        self.progress_due = Periodic(PROGRESS_PERIOD_S, time.monotonic).due
        self.log.info(
            f"MuJoCo {self.robot.version}: {len(self.joint_names)} joints {self.joint_names}, contacts "
            f"{self.robot.contacts or 'none'}, URDF collision shapes "
            f"{'kept' if self.config.shared.collision_geometry else 'dropped'}, step {self.config.step} s, "
            f"duration {self.config.duration or 'unbounded'} s"
        )
        self.status.say(RunStatus.CONFIGURED, 0.0)

    def on_command(self, data: bytes) -> None:
        try:
            values = read_checked(data, FLOAT64_MULTI_ARRAY, Float64MultiArray, self.limits).data
        except (wire.DecodeError, SizeError) as exc:
            self.log.limited("error", exc.kind, f"{COMMAND_TOPIC} refused: {exc}")
            return
        self.held.offer(values)

    def publish_state(self) -> None:
        """joint_states (effort: the held command), /clock, then each contact's wrench, at MuJoCo's time."""
        t_ns = self.steps * self.step_ns
        position, velocity = self.robot.state()
        self.joint_pub.publish(self.joint_wire.encode(t_ns, position, velocity, self.held.command))
        self.clock_pub.publish(self.clock_wire.encode(t_ns))
        for pub, force in zip(self.wrench_pubs, self.robot.contact_forces(), strict=True):
            pub.publish(self.wrench_wire.encode(t_ns, force))
        self.flow.sent()

    def advance(self) -> None:
        self.robot.step(self.held.command)
        self.steps += 1
        self.publish_state()
        if self.progress_due():
            self.status.say(RunStatus.PROGRESS, self.steps * self.config.step)

    def done(self) -> bool:
        return self.total_steps is not None and self.steps >= self.total_steps

    def finish(self) -> None:
        self.flow.wait()
        depth = self.robot.max_penetration
        self.get_logger().info(f"finished at t = {self.steps * self.config.step:.6f} s, deepest penetration {depth}")
        self.status.say(RunStatus.FINISHED, self.steps * self.config.step)
        self.status.flush()


def wait_for_peers(node: MujocoRobotNode, executor: SingleThreadedExecutor) -> None:
    """Before the first state: the recorder on every topic (wait_for_recorder), min_subscribers on
    joint_states (the controller too), a publisher of the commands (the controller), and run_status's
    subscribers (bracing-pair)."""
    cfg = node.config
    wait_until(
        node,
        executor,
        lambda: (
            (not cfg.wait_for_recorder or all(p.get_subscription_count() >= 1 for p in node.publishers_))
            and node.joint_pub.get_subscription_count() >= cfg.min_subscribers
            and node.command_sub.get_publisher_count() >= 1
            and node.status.subscribers() >= cfg.min_status_subscribers
        ),
        f"waiting for the recorder, the controller ({COMMAND_TOPIC}) and run_status's subscribers",
    )


def spin(node: MujocoRobotNode) -> int:
    executor = StoppableExecutor()
    executor.add_node(node)
    wait_for_peers(node, executor)  # stopped (Ctrl-C, SIGTERM, shutdown) anywhere: node_main.run ends the node
    node.status.say(RunStatus.STEPPING, 0.0)
    node.publish_state()
    while not node.done():
        node.held.wait_for_answer(lambda timeout_s: executor.spin_once(timeout_sec=timeout_s))
        node.advance()
    node.finish()
    return 0


def main(args: list[str] | None = None) -> int:
    sys.exit(run(MujocoRobotNode, spin, args))  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
