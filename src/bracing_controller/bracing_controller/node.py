"""bracing-controller: answers every joint_states with a motor_command (eq. 41 or 38).

Wiring only: ROS parameters -> ControllerConfig -> the core's answering policy
(``bracing_core.answering.StateAnswerer``: refusals, measurements, targets, the law and its checks);
the command is stamped with the state it answers, which is what the simulator's lockstep waits for.
A tunable parameter set while it runs is taken from the next state on (``StateAnswerer.retune``); a per-run one
(``bracing_core.run_parameters``: ``bracing``, ``free_space``) from the next run on: when the states go back in
time (the simulator's reset_simulation) the run is built from the parameters as they then are, as a fresh
process builds it (the law, the ControllerState layout, the brace targets' and force reports' subscriptions, the
per-state path); any other change is refused (it needs a fresh start).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
from geometry_msgs.msg import TwistStamped, Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import ClockType, ROSClock
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from rclpy.time import Time
from sensor_msgs.msg import JointState

from bracing_controller.effort_forward import EffortForward
from bracing_controller.rcl_path import RclPath, python_only
from bracing_controller.targets import TargetTopics
from bracing_core import run_parameters, schema
from bracing_core.answering import Answer, StateAnswerer
from bracing_core.controller_config import ControllerConfig
from bracing_core.gc_policy import SteppingCollector
from bracing_core.kinematics import WORLD_FRAME
from bracing_core.law import DecoupledController
from bracing_core.measurements import Measurements
from bracing_core.message_limits import SizeError
from bracing_core.mobile_base import CMD_VEL_TOPIC
from bracing_core.params import ConfigError
from bracing_core.stamps import stamp_ns
from bracing_core.step_timing import WorkTimer
from bracing_core.targets import ORIENTATION_ERROR_TOPIC
from bracing_core.typestore import MOTOR_STATE, TWIST_STAMPED, WRENCH_STAMPED
from bracing_msgs.msg import ControllerState, MotorCommand, MotorState, RunStatus
from bracing_ros import parameters, wire
from bracing_ros.ack_window import AckWindow
from bracing_ros.commands import MODE_CODES
from bracing_ros.matching import create_waking_publisher, wait_until
from bracing_ros.node_failure import end_run
from bracing_ros.node_log import RosNodeLog
from bracing_ros.node_main import run
from bracing_ros.qos import CMD_VEL_QOS, JOINT_STATE_QOS, STREAM_QOS, SUBSCRIBE_QOS
from bracing_ros.raw_messages import read_checked, read_joint_state
from bracing_ros.record_batch import RecordBatchPublisher
from bracing_ros.sim_clock import guard_clock
from bracing_ros.status import StatusPublisher
from bracing_ros.stop_signal import StoppableExecutor
from bracing_ros.waiter import SubscriptionWaiter

TEMPERATURE = ("", "motor_state")
"""The key of the windings' temperatures among the controller's measurement subscriptions."""


def measurement_keys(measurements: Measurements | None) -> list[tuple[str, str]]:
    """What ``measurements`` reads, in the order a fresh controller subscribes: (contact, topic) per fed-back force,
    then TEMPERATURE."""
    if measurements is None:
        return []
    keys = list(zip(measurements.forces, measurements.topics, strict=True))
    return [*keys, TEMPERATURE] if measurements.temperature else keys


class ControllerNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_controller", **kwargs)  # type: ignore[arg-type]
        values = schema.read("controller", parameters.given_parameters(self))
        self.config = config = ControllerConfig.from_values(values)
        self.status = StatusPublisher(self)  # what bracing-pair follows
        self.log = RosNodeLog(self, self.status, config.log_throttle_period)
        self.core = StateAnswerer(config, self.log)
        guard_clock(self, self.log)  # use_sim_time: a bad /clock refused, not fatal (before the clock is set below)
        # This node's clock is the sim time of the last state answered (``sync_clock``): rclpy stamps
        # the /parameter_events of a change with it, so a recorded change sits on the run's time axis
        # (the wall clock's stamp could not be placed on it). As a TimeSource does for use_sim_time,
        # without a /clock subscription on the lockstep path.
        clock = self.get_clock()
        assert isinstance(clock, ROSClock)  # a node's clock is
        self.clock = clock
        self.effort_forward = config.command_output == "effort_forward"
        if not self.effort_forward:  # effort_forward: its timer keeps the node's clock (use_sim_time: /clock)
            self.clock._set_ros_time_is_active(True)
        parameters.declare(self, "controller", values, checked=True)
        self.running = run_parameters.per_run_values("controller", parameters.current_values(self, "controller"))
        self.rebuilt = False  # a run built anew: the answering loop waits on its subscriptions, chooses its path
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.joint_names = self.core.joint_names
        contact_names = [c.name for c in config.shared.braced_contacts]
        # The wait for the recorder wakes on each match.
        self.command_pub = create_waking_publisher(self, MotorCommand, "motor_command", STREAM_QOS)
        self.state_pub = create_waking_publisher(self, ControllerState, "controller_state", STREAM_QOS)
        # The orientation task's error, only where there is one (a bag without the task has no new topic).
        self.orientation_pub = (
            create_waking_publisher(self, Vector3Stamped, ORIENTATION_ERROR_TOPIC, STREAM_QOS)
            if config.orientation.axes
            else None
        )
        self.orientation_wire = wire.Vector3StampedEncoder(WORLD_FRAME)
        answers = [self.command_pub, self.state_pub, *([self.orientation_pub] if self.orientation_pub else [])]
        # Messages travel as CDR bytes built by ``wire`` (rclpy's message classes cost more than the DDS write).
        self.command_wire = wire.MotorCommandEncoder(self.joint_names, MODE_CODES[config.shared.input_mode])
        self.state_wire = wire.ControllerStateEncoder(contact_names, len(self.joint_names))
        self.state_reader = wire.JointStateDecoder(self.joint_names, self.core.limits)  # sizes checked first
        # Force feedback and thermal compensation read contact_wrench/<name> and motor_state (``listen``): a
        # subscription per (contact, topic), or TEMPERATURE; the run's waited on with a state.
        self.measurement_subs: dict[tuple[str, str], Subscription] = {}
        self.measurement_waiter: SubscriptionWaiter | None = None
        self.wrench_subs: dict[Subscription, tuple[str, str]] = {}  # the run's: contact, its topic
        self.flow = AckWindow(self, answers, STREAM_QOS.depth)
        self.command_out: Callable[[], None] | None = None  # called once a command is out (lockstep's timing)
        # record_batch: the answers also reach the recorder in batches (it subscribes to those instead)
        self.batch = RecordBatchPublisher(self, answers, config.record_batch)
        self.core.start()
        self.effort = EffortForward(self, config, self.joint_names, self.log) if self.effort_forward else None
        self.target_topics = TargetTopics(self, self.core.targets, contact_names, self.log)
        # base_command cmd_vel: what a teleop or navigation stack sends, taken as diff_drive_controller takes it
        # (TwistStamped, the system default QoS), raw: its size checked before it is decoded
        self.cmd_vel_sub = (
            self.create_subscription(TwistStamped, CMD_VEL_TOPIC, self.on_cmd_vel, CMD_VEL_QOS, raw=True)
            if config.base_command == "cmd_vel"
            else None
        )
        self.status.say(RunStatus.CONFIGURED)

    def sync_clock(self) -> None:
        """Set this node's clock to the sim time of the last state answered (see ``__init__``)."""
        if self.effort_forward:
            return
        self.clock.set_ros_time_override(Time(nanoseconds=self.core.answered_ns, clock_type=ClockType.ROS_TIME))

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """A change while running (``bracing_core.run_parameters``): every one checked with the next run's
        parameters as a start with them would be; tunable ones to the core (from the next state on), per-run ones
        taken when the next run starts; any other refused."""
        given = [(change.name, parameters.plain(change.value)) for change in changes]
        current = parameters.current_values(self, "controller")
        reason = run_parameters.refusal("controller", [name for name, _ in given])
        per_run = run_parameters.per_run_changes("controller", given)
        pending = run_parameters.per_run_values("controller", current) != self.running
        if reason is None and (per_run or pending):  # else the retune's check is the next run's too
            try:
                law = DecoupledController(self.next_config(current | dict(given)))  # the next run's start
            except ConfigError as exc:
                reason = str(exc)
            else:  # the reports it reads subscribed to now: the simulator's writers match them before its first
                self.subscribe_measurements(Measurements.for_law(law), keep_others=True)
        live = [change for change in given if change not in per_run]
        if reason is None and live:
            reason = self.core.retune(run_parameters.running_values("controller", current, self.running), live)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        if per_run:
            self.log.info("from the next run: " + ", ".join(f"{name} = {value}" for name, value in per_run))
        return SetParametersResult(successful=True)

    def next_config(self, params: dict[str, Any]) -> ControllerConfig:
        """The configuration a fresh process started with ``params`` builds; a ConfigError as it would print it."""
        params = {**params, "robot.urdf": str(self.config.shared.urdf)}  # as this process resolved it
        return ControllerConfig.from_values(run_parameters.next_run_values("controller", params, []))

    def begin_run(self) -> None:
        """States went back in time: a new run. If a per-run parameter changed, the run is built from the
        parameters as they are now, as a fresh process builds it: the core (``StateAnswerer.rebuild``), the
        ControllerState layout, the brace targets' topics and the measurements' subscriptions (the answering
        loop then waits on them and chooses its per-state path again: ``rebuilt``)."""
        current = parameters.current_values(self, "controller")
        running = run_parameters.per_run_values("controller", current)
        if running == self.running:
            return
        self.running, self.config = running, self.next_config(current)
        self.core.rebuild(self.config)
        self.core.start()
        contact_names = [c.name for c in self.config.shared.braced_contacts]
        self.state_wire = wire.ControllerStateEncoder(contact_names, len(self.joint_names))
        self.state_reader = wire.JointStateDecoder(self.joint_names, self.core.limits)
        self.target_topics.retarget(self.core.targets, contact_names)
        self.use_measurements()
        if self.measurement_waiter is not None:  # what waits now is the run before's: this run reports after this
            self.measurement_waiter.take_all(0.0)  # state's answer
        self.rebuilt = True

    def listen(self) -> Subscription:
        """Subscribe to joint_states: from now on states are answered.

        With ``wait_for_recorder`` this comes only once the recorder subscribes to both outputs:
        the simulator starts stepping when this subscription appears (it waits for it), so no
        state is answered before the answers have somewhere to be recorded.
        """
        self.use_measurements()
        # joint_states last: the simulator steps once it matches this reader, and Fast DDS announces a
        # participant's endpoints in order on a reliable channel, so by then its contact_wrench and motor_state
        # writers have matched the readers above (created after it, step 0's reports could go out before they
        # matched and be lost: state 1 answered without them, 1 run in a loaded fresh-clone CI)
        return self.create_subscription(JointState, "joint_states", self.on_state, SUBSCRIBE_QOS, raw=True)

    def subscribe_measurements(self, measurements: Measurements | None, keep_others: bool = False) -> None:
        """Subscriptions to what ``measurements`` reads (force reports, the windings' temperatures), made where
        there are none yet; unless ``keep_others``, the ones it does not read destroyed."""
        wanted = measurement_keys(measurements)
        for key in wanted:
            if key not in self.measurement_subs:
                self.measurement_subs[key] = self.measurement_subscription(key)
        if not keep_others:
            for key in [key for key in self.measurement_subs if key not in wanted]:
                self.destroy_subscription(self.measurement_subs.pop(key))

    def measurement_subscription(self, key: tuple[str, str]) -> Subscription:
        """The subscription to one measurement: (contact, topic) of a force report, or TEMPERATURE. Raw: a message's
        sizes are checked before its elements are decoded. The executor (spun between states) and the waiter (while
        a state waits) both hand them to the core."""
        if key == TEMPERATURE:
            return self.create_subscription(MotorState, "motor_state", self.on_temperature, SUBSCRIBE_QOS, raw=True)
        contact, topic = key
        return self.create_subscription(
            WrenchStamped, topic, partial(self.on_wrench, contact, topic), SUBSCRIBE_QOS, raw=True
        )

    def use_measurements(self) -> None:
        """The run's measurements (the core's) subscribed to, only them, and waited on with a state."""
        self.subscribe_measurements(self.core.measurements)
        wanted = measurement_keys(self.core.measurements)
        self.wrench_subs = {self.measurement_subs[key]: key for key in wanted if key != TEMPERATURE}
        subs = [self.measurement_subs[key] for key in wanted]
        self.measurement_waiter = SubscriptionWaiter(self, subs) if subs else None

    def take_measurements(self, timeout_sec: float) -> None:
        """The force and temperature reports that have come (waiting up to ``timeout_sec`` for one)."""
        assert self.measurement_waiter is not None
        for subscription, msg in self.measurement_waiter.take_all(timeout_sec):
            if subscription in self.wrench_subs:
                self.on_wrench(*self.wrench_subs[subscription], msg)
            else:
                self.on_temperature(msg)

    def on_wrench(self, contact: str, topic: str, data: bytes) -> None:
        """A contact's measured force (CDR bytes, from ``topic``), to the core unless it cannot be read (none while
        the run reads no such force: subscribed for the next run)."""
        measurements = self.core.measurements
        if measurements is None or contact not in measurements.forces:
            return
        msg = self.read_measurement(data, topic, WRENCH_STAMPED, WrenchStamped)
        if msg is not None:
            f = msg.wrench.force
            self.core.take_force(contact, stamp_ns(msg.header.stamp), np.array([f.x, f.y, f.z]), msg.header.frame_id)

    def on_temperature(self, data: bytes) -> None:
        """The windings' temperatures (motor_state, CDR bytes), to the core unless they cannot be read (none while the
        run reads none: subscribed for the next run)."""
        if self.core.measurements is None or not self.core.measurements.temperature:
            return
        msg = self.read_measurement(data, "motor_state", MOTOR_STATE, MotorState)
        if msg is not None:
            self.core.take_temperature(stamp_ns(msg.header.stamp), np.asarray(msg.temperature, dtype=float))

    def on_cmd_vel(self, data: bytes) -> None:
        """A cmd_vel (CDR bytes) to the core, unless it cannot be read."""
        try:
            msg = self.read_measurement(data, CMD_VEL_TOPIC, TWIST_STAMPED, TwistStamped)
            if msg is not None:
                linear, angular = msg.twist.linear, msg.twist.angular
                self.core.take_cmd_vel(
                    stamp_ns(msg.header.stamp), [linear.x, linear.y, linear.z], [angular.x, angular.y, angular.z]
                )
        except Exception as exc:  # the last line of defence: no message may stop the controller
            self.log.limited("error", "internal", f"cmd_vel ignored: {type(exc).__name__}: {exc}")

    def read_measurement(self, data: bytes, topic: str, typename: str, msg_type: type) -> Any:
        """A measurement's message from ``topic``, or None after saying why it cannot be read (its size, its bytes)."""
        try:
            return read_checked(data, typename, msg_type, self.core.limits)
        except (wire.DecodeError, SizeError) as exc:
            self.log.limited("error", "measurement", f"ignored: {topic}: {exc}")
            return None

    def on_state(self, data: bytes) -> None:
        try:
            self.answer(data, ("error", "ignored", ""))
        except Exception as exc:  # the last line of defence: no message may stop the controller
            self.log.limited("error", "internal", f"joint_states ignored: {type(exc).__name__}: {exc}")

    def answer(self, data: bytes, refusal: tuple[str, str, str]) -> None:
        """Answer one joint_states (CDR bytes) with a motor_command and a controller_state, unless it is
        refused (``refusal``: severity, verdict and what follows, as ``StateAnswerer.read_state``)."""
        try:
            msg = read_joint_state(data, self.state_reader)
        except (wire.DecodeError, SizeError) as exc:
            severity, verdict, then = refusal
            self.log.limited(severity, exc.kind, f"joint_states {verdict}: {exc}{then}")
            return
        state = self.core.read_state(msg.name, msg.position, msg.velocity, msg.stamp_ns, refusal)
        if state is not None:
            if self.core.goes_back(msg.stamp_ns):
                self.begin_run()
            self.target_topics.apply(msg.stamp_ns)  # the latest of each that came: followed from this state on
            self.core.answer(msg.stamp_ns, *state, self.take_measurements, self.send)

    def send(self, answer: Answer) -> None:
        """The answer out: the command (motor_command, or effort_forward's topic) and the controller_state."""
        out, stamp_ns, publish = answer.output, answer.stamp_ns, self.batch.publish
        if self.effort is not None:
            self.effort.send(out.command)
        else:
            publish(self.command_pub, self.command_wire.encode(stamp_ns, out.command))
        if self.command_out is not None:
            self.command_out()  # the simulator's wait ends there; the controller_state follows it
        if self.orientation_pub is not None:  # before controller_state: a state's answer is complete with it
            publish(self.orientation_pub, self.orientation_wire.encode(stamp_ns, out.orientation_error))
        brace = (out.brace_desired, out.brace_actual)
        publish(
            self.state_pub,
            self.state_wire.encode(
                stamp_ns, out.hand_desired, out.hand_actual, answer.desired_normal_force, *brace, out.command,
                answer.compute_time,
            ),
        )  # fmt: skip
        self.flow.sent()
        self.batch.state_done()

    def recorder_matched(self) -> bool:
        """Whether a recorder subscribes to the answers (to the batches, with record_batch)."""
        if self.batch.publisher is not None:
            return self.batch.publisher.get_subscription_count() >= 1
        orientation = self.orientation_pub is None or self.orientation_pub.get_subscription_count() >= 1
        return (
            self.command_pub.get_subscription_count() >= 2
            and self.state_pub.get_subscription_count() >= 1
            and orientation
        )

    def close(self, timeout_sec: float) -> list[tuple[str, str]]:
        """At the stop: the recorder's copy of the answers (record_batch's batches, or else both topics)
        acknowledged, at most ``timeout_sec``; what did not happen, as (level, line) (none: all of it did).

        The stop waits for the recorder's copy only. The simulator's (motor_command, with record_batch)
        needs no flush: it has finished, stops with the run, or is gone; and a killed simulator's reader
        stays matched until its DDS lease ends (~20 s), so waiting for it only held the stop 10 s.
        """
        if self.batch.publisher is None:
            return self.flow.close(timeout_sec)
        self.batch.flush()
        lines = self.batch.flow.close(timeout_sec)
        topic = self.command_pub.topic_name
        if not self.command_pub.wait_for_all_acked(Duration(seconds=0)):
            names = ", ".join(sorted(i.node_name for i in self.get_subscriptions_info_by_topic(topic)))
            lines.append((
                "info",
                f"{topic}: the last answers are not acknowledged by {names or 'no subscriber'} "
                "(not waited for: the recorder has them in record_batch; the simulator has stopped or left)",
            ))  # fmt: skip
        return lines


def wait_for_outputs(node: ControllerNode, executor: SingleThreadedExecutor) -> None:
    """Before the first state: the recorder (wait_for_recorder) and the simulator on this node's outputs."""
    if node.config.wait_for_recorder:
        # Answers sent before the recorder has matched these publishers can be lost to it (a
        # recorder discovers late on a busy machine, and a short run ends before it does), so
        # no state is taken until then: joint_states is subscribed to only afterwards (the
        # executor would otherwise answer states from its callbacks while waiting here).
        waiting = "waiting for the recorder to subscribe to the command and state topics"
        wait_until(node, executor, node.recorder_matched, waiting)
    # An answer published before this writer has matched the simulator's reader is lost (volatile
    # durability), and the lockstep simulator would wait its command_timeout for it (seen in CI:
    # the simulator matched both endpoints first and stalled 5 s on its first state).
    wait_until(
        node,
        executor,
        lambda: node.command_pub.get_subscription_count() >= 1,
        "waiting for a subscriber of motor_command (start the simulator)",
    )


def spin(node: ControllerNode) -> int:
    """Answer states until stopped (``answer_states``, or effort_forward's loop); an exception that ends the run
    (the C++ path's, or the loop's) said, the answers flushed, exit 1 (``bracing_ros.node_failure``)."""
    try:
        return spin_effort_forward(node) if node.effort is not None else answer_states(node)
    except ExternalShutdownException:
        return 0
    except Exception as exc:
        return end_run(node.get_logger(), exc, lambda: flush_answers(node))


def answer_states(node: ControllerNode) -> int:
    """Answer states as they come (one wait set on joint_states and the targets), serving the executor
    in between."""
    executor = StoppableExecutor()
    executor.add_node(node)
    answered, work, targets = 0, WorkTimer(), node.target_topics
    rcl: RclPath | None = None
    collector = SteppingCollector()  # no automatic garbage collection on a state's answer
    try:
        wait_for_outputs(node, executor)
        state_sub = node.listen()
        waiter, rcl = answering_waits(node, state_sub)
        node.log.info("answering joint_states")
        node.command_out = work.mark
        collector.start()
        node.status.say(RunStatus.STEPPING)
        while True:
            if node.rebuilt:  # a run built anew (per-run parameters): its subscriptions, its per-state path
                node.rebuilt = False
                waiter, rcl = answering_waits(node, state_sub)
            if rcl is None:
                states, taken = 0, waiter.take_all(0.1)
            else:  # the C++ path waits for the states and answers them, this loop takes the rest
                states, ready = rcl.serve(work, max(100 - answered, 1))
                taken = [] if node.rebuilt else waiter.take_ready(ready)  # rebuilt: taken by the new wait
                answered += states
            for subscription, msg in taken:
                if subscription is state_sub:
                    work.begin()
                    node.on_state(msg)
                    work.end(node.batch.take_written())
                    states += 1
                elif subscription is node.cmd_vel_sub:
                    node.on_cmd_vel(msg)
                else:  # kept, the latest of each topic (states are taken first: followed from the next state on)
                    targets.take(subscription, msg)
            answered += len(taken)  # states and targets alike: a flood of targets spins the executor no more
            if not states:
                node.batch.flush()  # the stream paused (or ended): what waits goes to the recorder now
            if not (taken or states) or answered >= 100:
                answered = 0
                node.sync_clock()  # a parameter change is stamped with it
                executor.spin_once(timeout_sec=0.0)  # parameter services and the like
                collector.safe_point()
    except KeyboardInterrupt:
        if (line := work.line()) is not None:
            node.log.info(line)  # make bench's pair_step_breakdown_us
        if rcl is not None:
            node.log.info(rcl.line())
        # Stopped (bracing-pair stops the controller once the simulator is done): the last
        # answers must reach the recorder before this process and its publishers are gone.
        flush_answers(node)
        return 0
    except ExternalShutdownException:
        return 0
    finally:
        collector.stop()


def flush_answers(node: ControllerNode) -> None:
    """At the stop (or a failure): the answers sent reach the recorder (at most 10 s); what did not, said."""
    for k, (level, line) in enumerate(node.close(timeout_sec=10.0)):
        node.log.limited(level, f"stop-{k}", f"stopping: {line}")  # each said (a kind of its own)


def answering_waits(node: ControllerNode, state_sub: Subscription) -> tuple[SubscriptionWaiter, RclPath | None]:
    """The answering loop's wait on joint_states, the targets and cmd_vel, and its C++ path (None: Python's)."""
    # The targets in the same wait: a wait of their own on every state cost ~15 % of the node's time (py-spy).
    commands = [node.cmd_vel_sub] if node.cmd_vel_sub is not None else []
    others = [*node.target_topics.subscriptions, *commands]
    return SubscriptionWaiter(node, [state_sub, *others]), answer_on_rcl(node, state_sub, others)


def answer_on_rcl(node: ControllerNode, state_sub: Subscription, others: list[Subscription]) -> RclPath | None:
    """The C++ path on rcl for the states (waiting with ``others`` too), if the run needs nothing it leaves out
    (``rcl_path``); which, logged."""
    reason = python_only(node.core, node.effort is not None, node.orientation_pub is not None)
    node.log.info(f"per-state path: {'Python (' + reason + ')' if reason else 'C++ on rcl'}")
    return RclPath(node, state_sub, others) if reason is None else None


def effort_tick(node: ControllerNode) -> None:
    """One control period: the law on the latest state, unless it is refused (or there is none yet), or
    older than state_timeout (then zero efforts, once a state has been answered: ``StateFreshness``)."""
    effort = node.effort
    assert effort is not None
    if effort.latest is None:
        return
    try:
        freshness = effort.freshness
        now_ns = effort.now_ns() if freshness.enabled else 0
        if freshness.usable(now_ns):
            node.answer(effort.latest, ("warning", "refused", "; no command sent"))
        if freshness.zero_due(now_ns):
            effort.send_zeros()
    except Exception as exc:  # the last line of defence: no state may stop the controller
        node.log.limited("error", "internal", f"joint_states ignored: {type(exc).__name__}: {exc}")


def spin_effort_forward(node: ControllerNode) -> int:
    """Subscribe joint_states, then send the law's efforts at control_rate until stopped."""
    effort = node.effort
    assert effort is not None
    executor = StoppableExecutor()
    executor.add_node(node)
    node.create_subscription(JointState, "joint_states", effort.on_state, JOINT_STATE_QOS, raw=True)
    node.create_timer(1.0 / node.config.control_rate, lambda: effort_tick(node))
    node.get_logger().info(
        f"effort_forward: {node.config.effort_command_topic} at {node.config.control_rate:g} Hz, joints {effort.joints}"
    )
    node.status.say(RunStatus.STEPPING)
    # Never one endless wait: under use_sim_time with /clock stopped, rclpy's wait would not return, and the
    # Python signal handlers (SIGINT, SIGTERM: bracing_ros.node_main.run, which ends the node) would never run.
    while True:
        executor.spin_once(timeout_sec=0.1)


def main(args: list[str] | None = None) -> int:
    sys.exit(run(ControllerNode, spin, args))  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
