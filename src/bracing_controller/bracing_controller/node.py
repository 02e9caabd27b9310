"""bracing-controller: answers every joint_states with a motor_command (eq. 41 or 38).

Thin: ROS parameters -> ControllerConfig -> DecoupledController; the command is
stamped with the state it answers, which is what the simulator's lockstep waits for.
"""

from __future__ import annotations

import sys
import time
from functools import partial

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import ClockType, ROSClock
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from rclpy.time import Time
from sensor_msgs.msg import JointState

from bracing_controller.effort_forward import STATE_QOS, EffortForward
from bracing_controller.states import StateError, joint_vectors
from bracing_controller.targets import TargetTopics, task_targets
from bracing_core import schema
from bracing_core.checks import configuration_warnings, desired_force_warning, null_space_warning
from bracing_core.controller_config import ControllerConfig
from bracing_core.law import ControlOutput, DecoupledController
from bracing_core.measurements import Measurements
from bracing_core.params import ConfigError
from bracing_core.types import Vector
from bracing_msgs.msg import ControllerState, MotorCommand, MotorState, RunStatus
from bracing_ros import parameters, wire
from bracing_ros.commands import MODE_CODES
from bracing_ros.common import (
    STREAM_QOS,
    SUBSCRIBE_QOS,
    AckWindow,
    RateLimitedLog,
    SubscriptionWaiter,
    create_waking_publisher,
    read_joint_state,
    run,
    wait_until,
)
from bracing_ros.status import StatusPublisher

STAMP_RANGE_NS = (-(2**31) * 1_000_000_000, 2**31 * 1_000_000_000)
NULL_SPACE_CHECK_EVERY = 20
"""States between two looks at the null space's speed (1 us each in the engine; a runaway lasts 100s of steps)."""
MEASUREMENT_WAIT_S = 0.5
"""[s] wall: how long a state waits for the force and temperature reports of the step before it
(``Measurements``); past it the state is answered with the latest ones, and a warning says which lagged."""


class ControllerNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_controller", **kwargs)  # type: ignore[arg-type]
        values = schema.read("controller", parameters.given_parameters(self))
        self.config = ControllerConfig.from_values(values)
        self.law = DecoupledController(self.config)
        # This node's clock is the sim time of the last state answered (``sync_clock``): rclpy stamps
        # the /parameter_events of a change with it, so a recorded change sits on the run's time axis
        # (the wall clock's stamp could not be placed on it). As a TimeSource does for use_sim_time,
        # without a /clock subscription on the lockstep path.
        self.answered_ns = 0  # [ns] the stamp of the last state answered
        clock = self.get_clock()
        assert isinstance(clock, ROSClock)  # a node's clock is
        self.clock = clock
        self.effort_forward = self.config.command_output == "effort_forward"
        if not self.effort_forward:  # effort_forward: its timer keeps the node's clock (use_sim_time: /clock)
            self.clock._set_ros_time_is_active(True)
        parameters.declare(self, "controller", values)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.retuned: ControllerConfig | None = None  # applied at the next update
        self.joint_names = list(self.law.plant.joint_names)
        self.mode_code = MODE_CODES[self.config.shared.input_mode]
        self.contact_names = [c.name for c in self.config.shared.braced_contacts]
        # The wait for the recorder wakes on each match.
        self.command_pub = create_waking_publisher(self, MotorCommand, "motor_command", STREAM_QOS)
        self.state_pub = create_waking_publisher(self, ControllerState, "controller_state", STREAM_QOS)
        # Messages travel as CDR bytes built by ``wire`` (rclpy's message classes cost more than the DDS write).
        self.command_wire = wire.MotorCommandEncoder(self.joint_names, self.mode_code)
        self.state_wire = wire.ControllerStateEncoder(self.contact_names, len(self.joint_names))
        self.state_reader = wire.JointStateDecoder(self.joint_names)
        self.state_sub: Subscription | None = None  # see ``listen``
        # Force feedback and thermal compensation read contact_wrench/<name> and motor_state.
        self.measurements = Measurements.for_law(self.law)
        self.measurement_waiter: SubscriptionWaiter | None = None
        self.wrench_subs: dict[Subscription, str] = {}
        self.previous_ns: int | None = None  # the stamp of the last state answered (None: none yet)
        self.null_space_warned = False
        self.answers = 0  # states answered (the null-space watch samples them)
        self.report = RateLimitedLog(self, self.config.log_throttle_period)
        self.flow = AckWindow(self, [self.command_pub, self.state_pub], STREAM_QOS.depth)
        self.get_logger().info(
            f"{self.config.shared.input_mode.value} output, contacts {self.contact_names or 'none'}, "
            f"task dimension {self.config.task_dimension}"
        )
        for warning in configuration_warnings(self.config, self.law.plant):  # before the run, once
            self.get_logger().warning(warning)
        self.effort = EffortForward(self, self.config, self.joint_names) if self.effort_forward else None
        self.targets = task_targets(self.law)
        self.target_topics = TargetTopics(self, self.targets, self.contact_names)
        self.status = StatusPublisher(self)  # what bracing-pair follows
        self.status.say(RunStatus.CONFIGURED)

    def follow_targets(self, t: float) -> None:
        """Feed the law each retargeted task's reference at t (hand_target, hand_path, brace_target/<contact>)."""
        if not self.targets.goals or self.previous_ns is None:  # no target, or the law has no path start yet
            return
        for task, (position, velocity) in self.targets.advance(t, self.law.engine.path_sample).items():
            self.law.engine.set_reference(task, position, velocity)

    def sync_clock(self) -> None:
        """Set this node's clock to the sim time of the last state answered (see ``__init__``)."""
        if self.effort_forward:
            return
        self.clock.set_ros_time_override(Time(nanoseconds=self.answered_ns, clock_type=ClockType.ROS_TIME))

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """A set of tunable parameters (rclpy refuses read-only ones before this): validated as a
        whole configuration, applied from the next update, logged."""
        values = parameters.current_values(self, "controller")
        for change in changes:
            param = schema.find("controller", change.name)
            if param is None or not param.tunable:
                return SetParametersResult(successful=False, reason=f"{change.name}: cannot change while running")
            values[change.name] = parameters.plain(change.value)
        values["robot.urdf"] = str(self.config.shared.urdf)
        try:
            config = ControllerConfig.from_params(values)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.retuned = config
        listed = ", ".join(f"{c.name} = {parameters.plain(c.value)}" for c in changes)
        self.get_logger().info(f"retuned (from the next update): {listed}")
        changed = {change.name for change in changes}
        for contact in config.shared.braced_contacts:
            if f"contacts.{contact.name}.desired_normal_force" in changed:
                warning = desired_force_warning(
                    contact.name, contact.desired_normal_force or 0.0, self.answered_ns * 1e-9
                )
                if warning is not None:
                    self.get_logger().warning(warning)
        return SetParametersResult(successful=True)

    def listen(self) -> Subscription:
        """Subscribe to joint_states: from now on states are answered.

        With ``wait_for_recorder`` this comes only once the recorder subscribes to both outputs:
        the simulator starts stepping when this subscription appears (it waits for it), so no
        state is answered before the answers have somewhere to be recorded.
        """
        self.state_sub = self.create_subscription(JointState, "joint_states", self.on_state, SUBSCRIBE_QOS, raw=True)
        if self.measurements is not None:
            # the executor (spun between states) and the waiter (while a state waits) both hand them to on_measurement
            self.wrench_subs = {
                self.create_subscription(WrenchStamped, topic, partial(self.on_wrench, name), SUBSCRIBE_QOS): name
                for name, topic in zip(self.measurements.forces, self.measurements.topics, strict=True)
            }
            subs = list(self.wrench_subs)
            if self.measurements.temperature:
                subs.append(self.create_subscription(MotorState, "motor_state", self.on_temperature, SUBSCRIBE_QOS))
            self.measurement_waiter = SubscriptionWaiter(self, subs)
        return self.state_sub

    def take_measurements(self, timeout_sec: float) -> None:
        """The force and temperature reports that have come (waiting up to ``timeout_sec`` for one)."""
        assert self.measurement_waiter is not None
        for subscription, msg in self.measurement_waiter.take_all(timeout_sec):
            if subscription in self.wrench_subs:
                self.on_wrench(self.wrench_subs[subscription], msg)
            else:
                self.on_temperature(msg)

    def on_wrench(self, contact: str, msg: WrenchStamped) -> None:
        """Keep a contact's measured force (contact_wrench/<contact>)."""
        assert self.measurements is not None
        f = msg.wrench.force
        problem = self.measurements.take_force(contact, _stamp_ns(msg), np.array([f.x, f.y, f.z]), msg.header.frame_id)
        if problem is not None:
            self.report("error", "measurement", f"ignored: {problem}")

    def on_temperature(self, msg: MotorState) -> None:
        """Keep the windings' measured temperatures (motor_state)."""
        assert self.measurements is not None
        problem = self.measurements.take_temperature(_stamp_ns(msg), np.array(msg.temperature), len(self.joint_names))
        if problem is not None:
            self.report("error", "measurement", f"ignored: {problem}")

    def measure(self) -> None:
        """Give the law the reports of the step before this state (``Measurements``), waiting briefly for them."""
        if self.measurements is None:
            return
        deadline = time.monotonic() + MEASUREMENT_WAIT_S
        self.take_measurements(0.0)
        while not self.measurements.ready(self.previous_ns) and (left := deadline - time.monotonic()) > 0.0:
            self.take_measurements(min(left, 0.05))
        if self.previous_ns is not None and not self.measurements.ready(self.previous_ns):
            lagging = ", ".join(self.measurements.missing(self.previous_ns))
            self.report("warning", "lagging", f"no report of the last step within {MEASUREMENT_WAIT_S} s: {lagging}")
        self.measurements.apply(self.law)

    def watch_null_space(self, out: ControlOutput, dq: Vector, t: float) -> None:
        """Every NULL_SPACE_CHECK_EVERY states, until said once: warn of joints running in the null space."""
        self.answers += 1
        if self.null_space_warned or self.answers % NULL_SPACE_CHECK_EVERY:
            return
        hand_error = float(np.linalg.norm(out.hand_desired - out.hand_actual))
        warning = null_space_warning(self.law.null_space_speed(dq), hand_error, t)
        if warning is not None:
            self.null_space_warned = True
            self.get_logger().warning(warning)
            self.status.warn(warning, t)  # the recorder keeps it for the summary, as the simulator's

    def on_state(self, data: bytes) -> None:
        try:
            self.answer(data)
        except Exception as exc:  # the last line of defence: no message may stop the controller
            self.report("error", "internal", f"joint_states ignored: {type(exc).__name__}: {exc}")

    def answer(self, data: bytes) -> None:
        """Answer one joint_states (CDR bytes) with a motor_command and a controller_state."""
        state = self.read_state(data, "error", "ignored")
        if state is not None:
            self.respond(*state)

    def read_state(self, data: bytes, severity: str, verdict: str, then: str = "") -> tuple[int, Vector, Vector] | None:
        """(stamp [ns], q, dq) of one joint_states (CDR bytes) in the law's joint order, or None after
        reporting, at ``severity``, why it is ``verdict`` (malformed, a joint missing, non-finite, ...)."""
        try:
            msg = read_joint_state(data, self.state_reader)
            q, dq = joint_vectors(msg, self.joint_names)
        except wire.DecodeError as exc:
            self.report(severity, "malformed", f"joint_states {verdict}: {exc}{then}")
            return None
        except StateError as exc:
            self.report(severity, str(exc).split(" ")[0], f"joint_states {verdict}: {exc}{then}")
            return None
        return msg.stamp_ns, q, dq

    def respond(self, stamp_ns: int, q: Vector, dq: Vector) -> None:
        """The law's answer to the state (q, dq) stamped ``stamp_ns``: the command and the controller_state."""
        if self.retuned is not None:
            self.law.retune(self.retuned)
            self.config, self.retuned = self.retuned, None
        t = stamp_ns * 1e-9
        self.measure()
        self.follow_targets(t)
        start = time.perf_counter()
        try:
            out = self.law.update(t, q, dq)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:  # absurd but finite q, dq
            self.report("error", "law", f"joint_states at t = {t:.6f} s ignored: the law failed on it ({exc})")
            return
        compute_time = time.perf_counter() - start
        outputs = (out.command, out.hand_desired, out.hand_actual, out.desired_normal_force)
        if not all(np.isfinite(v).all() for v in (*outputs, out.brace_desired, out.brace_actual)):
            self.report("error", "command", f"joint_states at t = {t:.6f} s ignored: the law's output is not finite")
            return
        if out.damped:
            self.report("warning", "damped", "B is near-singular: using a damped inverse")
        self.watch_null_space(out, dq, t)
        if self.effort is not None:
            self.effort.send(out.command)
        else:
            self.command_pub.publish(self.command_wire.encode(stamp_ns, out.command))
        self.state_pub.publish(
            self.state_wire.encode(
                stamp_ns,
                out.hand_desired,
                out.hand_actual,
                out.desired_normal_force,
                out.brace_desired,
                out.brace_actual,
                out.command,
                compute_time,
            )
        )
        self.answered_ns = self.previous_ns = stamp_ns
        self.flow.sent()


def _stamp_ns(msg: WrenchStamped | MotorState) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def spin(node: ControllerNode) -> int:
    """Answer states as they come (a wait set on joint_states), serving the executor in between."""
    if node.effort is not None:
        return spin_effort_forward(node)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    answered = 0
    try:
        if node.config.wait_for_recorder:
            # Answers sent before the recorder has matched these publishers can be lost to it (a
            # recorder discovers late on a busy machine, and a short run ends before it does), so
            # no state is taken until then: joint_states is subscribed to only afterwards (the
            # executor would otherwise answer states from its callbacks while waiting here).
            wait_until(
                node,
                executor,
                lambda: node.command_pub.get_subscription_count() >= 2 and node.state_pub.get_subscription_count() >= 1,
                "waiting for the recorder to subscribe to the command and state topics",
            )
        # An answer published before this writer has matched the simulator's reader is lost (volatile
        # durability), and the lockstep simulator would wait its command_timeout for it (seen in CI:
        # the simulator matched both endpoints first and stalled 5 s on its first state).
        wait_until(
            node,
            executor,
            lambda: node.command_pub.get_subscription_count() >= 1,
            "waiting for a subscriber of motor_command (start the simulator)",
        )
        waiter = SubscriptionWaiter(node, node.listen())
        node.get_logger().info("answering joint_states")
        node.status.say(RunStatus.STEPPING)
        while True:
            messages = waiter.take(0.1)
            for msg in messages:
                node.on_state(msg)
            answered += len(messages)
            node.target_topics.poll()  # a target is followed from the next state on
            if not messages or answered >= 100:
                answered = 0
                node.sync_clock()  # a parameter change is stamped with it
                executor.spin_once(timeout_sec=0.0)  # parameter services and the like
    except KeyboardInterrupt:
        # Stopped (bracing-pair stops the controller once the simulator is done): the last
        # answers must reach the recorder before this process and its publishers are gone.
        if not node.flow.wait(timeout_sec=10.0):
            node.get_logger().error("stopping with answers that a subscriber has not acknowledged (lost to it)")
        return 0
    except ExternalShutdownException:
        return 0


def effort_tick(node: ControllerNode) -> None:
    """One control period: the law on the latest state, unless it is refused (or there is none yet)."""
    effort = node.effort
    assert effort is not None
    data = effort.latest
    if data is None:
        return
    state = node.read_state(data, "warning", "refused", "; no command sent")
    if state is None:
        return
    try:
        node.respond(*state)
    except Exception as exc:  # the last line of defence: no state may stop the controller
        node.report("error", "internal", f"joint_states ignored: {type(exc).__name__}: {exc}")


def spin_effort_forward(node: ControllerNode) -> int:
    """Subscribe joint_states, then send the law's efforts at control_rate until stopped."""
    effort = node.effort
    assert effort is not None
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    node.create_subscription(JointState, "joint_states", effort.on_state, STATE_QOS, raw=True)
    node.create_timer(1.0 / node.config.control_rate, lambda: effort_tick(node))
    node.get_logger().info(
        f"effort_forward: {node.config.effort_command_topic} at {node.config.control_rate:g} Hz, joints {effort.joints}"
    )
    node.status.say(RunStatus.STEPPING)
    try:
        # Never one endless wait: under use_sim_time with /clock stopped, rclpy's wait would not return,
        # and the Python signal handlers (SIGINT, SIGTERM: bracing_ros.common.run) would never run.
        while True:
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    return 0


def main(args: list[str] | None = None) -> int:
    sys.exit(run(ControllerNode, spin, args))  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
