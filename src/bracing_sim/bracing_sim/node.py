"""bracing-simulator: publishes the simulated robot, applies motor commands.

Thin: ROS parameters -> SimulatorConfig -> core Simulator; messages in and out.
Lockstep (default): publish state k, wait for the command stamped with state k's
stamp, step with it held. Real-time: a wall-clock timer steps with the latest command.
"""

from __future__ import annotations

import math
import sys
import time
from functools import partial

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from bracing_core import schema
from bracing_core.checks import REAL_TIME_ACHIEVED
from bracing_core.config import SimulatorConfig, build_simulator
from bracing_core.drive import CurrentLoopDrive, DriveGains
from bracing_core.dynamics import Derivative, InputMode
from bracing_core.meshes import missing_warning
from bracing_core.sensing import GROUND_TRUTH
from bracing_core.simulator import DivergenceError, Energy
from bracing_core.types import Vector
from bracing_core.watch import RunWatch
from bracing_msgs.msg import Contacts, MotorCommand, MotorState, RunStatus
from bracing_ros import parameters, wire
from bracing_ros.commands import MODE_CODES, CommandError, command_vector, effort_vector
from bracing_ros.common import (
    EXIT_DIVERGED,
    STREAM_QOS,
    SUBSCRIBE_QOS,
    AckWindow,
    RateLimitedLog,
    SubscriptionWaiter,
    create_waking_publisher,
    read_motor_command,
    run,
    wait_until,
)
from bracing_ros.status import StatusPublisher

DESCRIPTION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""robot_description as robot_state_publisher offers it: one message, kept for late subscribers."""


JOINT_COMMANDS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""robot_joint_commands / robot_joint_states, as ros-controls/topic_based_hardware_interfaces'
joint_state_topic_hardware_interface/src/joint_state_topic_hardware_interface.cpp has them: its
commands go out with rclcpp::QoS(1) (reliable, volatile, depth 1), one JointState with every joint's
name in its own order and only the declared command interfaces filled (here `effort`), unless
trigger_joint_command_threshold holds them back; it reads the state with SensorDataQoS (best effort,
the latest message kept), joints matched by name, only finite position/velocity/effort used. A
reliable subscription matches its publisher, a reliable publisher its best-effort reader."""



class SimulatorNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_simulator", **kwargs)  # type: ignore[arg-type]
        values = schema.read("simulator", parameters.given_parameters(self))
        self.config = SimulatorConfig.from_values(values)
        parameters.declare(self, "simulator", values)  # read-only: nothing changes during a run
        self.plant, self.sim = build_simulator(self.config)
        self.joint_names = list(self.plant.joint_names)
        self.mode = self.config.shared.input_mode
        motors = self.plant.motors
        self.limit = motors.voltage_limit if self.mode is InputMode.VOLTAGE else motors.torque_limit
        self.step_ns = round(self.config.step * 1e9)
        duration = self.config.duration
        self.total_steps = round(duration / self.config.step) if duration > 0 else None

        publisher = partial(create_waking_publisher, self)  # the lockstep wait wakes on each match
        self.joint_pub = publisher(JointState, "joint_states", STREAM_QOS)
        self.contacts_pub = publisher(Contacts, "contacts", STREAM_QOS)
        self.motor_pub = publisher(MotorState, "motor_state", STREAM_QOS)
        self.clock_pub = publisher(Clock, "/clock", STREAM_QOS)
        # A wrench topic per configured contact (the contact set lists them first); the contacts a
        # collision frame adds are reported in `contacts` only.
        self.wrench_pubs = [
            publisher(WrenchStamped, f"contact_wrench/{c.name}", STREAM_QOS) for c in self.config.shared.contacts
        ]
        # The URDF loaded, as simulated (each locked joint a fixed joint at its locked position; the
        # URDF itself when none is locked), latched: robot_state_publisher, RViz, Foxglove and the
        # recorder get it whenever they join, and with joint_states (the moving joints) pose the
        # links where the simulator has them.
        self.description_pub = publisher(String, "robot_description", DESCRIPTION_QOS)
        # What the controller receives, as a real arm measures it (sensors.*); the truth then goes out too.
        sensing = self.config.sensors
        self.sensors = None if sensing.exact else sensing.engine(self.config.step, self.plant.robot.prismatic.tolist())
        self.truth_pubs = []
        if self.sensors is not None:
            self.truth_pubs = [
                publisher(JointState, GROUND_TRUTH + "joint_states", STREAM_QOS),
                publisher(MotorState, GROUND_TRUTH + "motor_state", STREAM_QOS),
            ]
        # Its meshes as file:// paths of the files found here (robot.package_paths): viewers need no package index.
        description, missing_meshes = self.plant.description()
        self.description_pub.publish(String(data=description))
        # Messages travel as CDR bytes built by ``wire`` (rclpy's message classes cost more than the DDS write).
        contacts = self.plant.contact_set.contacts
        self.joint_wire = wire.JointStateEncoder(self.joint_names)
        self.clock_wire = wire.ClockEncoder()
        self.wrench_wire = wire.WrenchStampedEncoder("world")
        self.contacts_wire = wire.ContactsEncoder([c.name for c in contacts], [c.frame for c in contacts])
        self.motor_wire = wire.MotorStateEncoder(self.joint_names)
        self.command_reader = wire.MotorCommandDecoder(self.joint_names, MODE_CODES[self.mode])
        self.command_sub: Subscription | None = None  # motor_command (command_source motor_command)
        if self.config.command_source == "motor_command":
            self.command_sub = self.create_subscription(
                MotorCommand, "motor_command", self.on_command, SUBSCRIBE_QOS, raw=True
            )
        self.drive: CurrentLoopDrive | None = None  # joint_commands in voltage mode: effort -> voltage
        self.joint_command_pubs: list[Publisher] = []  # joint_commands: robot_joint_states
        if self.config.command_source == "joint_commands":
            self.listen_joint_commands()
        self.report = RateLimitedLog(self, self.config.log_throttle_period)
        # robot_description too: a short run could otherwise end before the recorder has it.
        self.publishers_ = [
            self.joint_pub,
            self.contacts_pub,
            self.motor_pub,
            self.clock_pub,
            *self.wrench_pubs,
            self.description_pub,
            *self.truth_pubs,
        ]
        self.flow = AckWindow(self, self.publishers_, STREAM_QOS.depth)
        self.status = StatusPublisher(self)  # what bracing-pair follows (not a data topic: not in publishers_)
        self.real_time_achieved = math.nan  # real-time stepping: sim time / wall time, once finished

        self.command = np.zeros(self.sim.n)  # last applied (held) command
        self.pending: dict[int, Vector] = {}  # lockstep: valid commands by stamp [ns]
        self.latest_command: tuple[float, Vector] | None = None  # real-time: (wall time, command)
        self._next_progress = 0.0  # wall time of the next progress line
        self.max_residual = 0.0  # [m], over the run so far (contacts holding a force)
        self._events_logged = 0
        # What the run should be warned about (policy in the core: the in-process rollout says the same);
        # each warning goes to the log and to run_status, whence the recorder puts it in the bag (``say``).
        self.watch = RunWatch(self.plant, self.config, self.sim)
        self.refusal = ""  # why the last refused step was refused
        self.get_logger().info(
            f"{self.mode.value} input, {len(self.plant.contact_set)} contact(s), step {self.config.step} s, "
            f"{self.config.stepping}, duration {duration or 'unbounded'} s"
        )
        if self.sim.substeps > self.config.substeps:
            self.get_logger().info(
                f"stiff motor circuits: {self.sim.substeps} RK4 sub-steps per step (substeps {self.config.substeps})"
            )
        if self.config.project_initial_position:
            given = self.plant.to_model_order(self.config.initial_position)
            projected = dict(zip(self.joint_names, self.sim.position.round(9).tolist(), strict=True))
            moved = float(np.max(np.abs(self.sim.position - given)))
            self.get_logger().info(
                f"initial position projected onto the contacts: {projected} (moved {moved:.3g} at most)"
            )
        self.say(([missing_warning(missing_meshes)] if missing_meshes else []) + self.watch.start())
        self.status.say(RunStatus.CONFIGURED, self.sim.time)

    def say(self, warnings: list[str]) -> None:
        """Each warning about the run in the log and on run_status (the recorder keeps it for the summary)."""
        for warning in warnings:
            self.get_logger().warning(warning)
            self.status.warn(warning, self.sim.time)

    def warn_report(self, kind: str, message: str) -> None:
        """A warning the log repeats (rate-limited per kind): the first of its kind is said in full (``say``),
        the rest are counted by the log."""
        first = self.watch.once(kind, message, self.sim.time)
        if first:
            self.say(first)
            self.report.mark(kind)  # the limiter counts on from this one
        else:
            self.report("warning", kind, message)

    def listen_joint_commands(self) -> None:
        """command_source joint_commands: efforts as ros2_control's JointStateTopicSystem sends them (a
        current-loop drive turns them into voltages in voltage mode), the state published for it too."""
        cfg = self.config
        self.create_subscription(JointState, cfg.joint_commands_topic, self.on_joint_command, JOINT_COMMANDS_QOS)
        self.joint_command_pubs = [self.create_publisher(JointState, cfg.joint_states_topic, JOINT_COMMANDS_QOS)]
        if self.mode is InputMode.VOLTAGE:
            motors = self.plant.motors
            gains = DriveGains.from_bandwidth(
                cfg.motor_drive.bandwidth,
                motors.inductance,
                motors.resistance,
                self.plant.to_model_order(cfg.motor_drive.kp) if cfg.motor_drive.kp else (),
                self.plant.to_model_order(cfg.motor_drive.ki) if cfg.motor_drive.ki else (),
            )
            self.drive = CurrentLoopDrive(gains, motors.reflected_constant, motors.voltage_limit)
        self.get_logger().info(
            f"joint_commands: efforts from {cfg.joint_commands_topic}, state also on {cfg.joint_states_topic}"
            + (f", current loop {cfg.motor_drive.bandwidth:g} rad/s" if self.drive is not None else "")
        )

    def on_joint_command(self, msg: JointState) -> None:
        """Keep the latest valid JointState effort command [N m or N, link side] (real-time: held)."""
        try:
            torque_limit = self.plant.motors.torque_limit if self.drive is None else 0.0
            u, saturated = effort_vector(list(msg.name), list(msg.effort), self.joint_names, torque_limit)
        except CommandError as exc:
            self.report("error", exc.kind, f"{self.config.joint_commands_topic} rejected: {exc}")
            return
        except Exception as exc:  # the last line of defence: no message may stop the simulator
            self.report("error", "internal", f"joint command rejected: {type(exc).__name__}: {exc}")
            return
        if saturated:
            self.report("warning", "saturated", f"{self.config.joint_commands_topic} saturated to +/-{torque_limit}")
        self.latest_command = (time.monotonic(), u)

    def applied(self, request: Vector) -> Vector:
        """What the plant gets for a held request: the request itself, or with the drive (joint_commands in
        voltage mode) the voltage its current loop sets for this step."""
        if self.drive is None:
            return request
        return self.drive.voltage(request, self.sim.current, self.sim.velocity, self.config.step)

    # -- commands -------------------------------------------------------------------
    def on_command(self, data: bytes) -> None:
        try:
            self.take_command(data)
        except Exception as exc:  # the last line of defence: no message may stop the simulator
            self.report("error", "internal", f"motor_command rejected: {type(exc).__name__}: {exc}")

    def take_command(self, data: bytes) -> None:
        """Validate one motor_command (CDR bytes) and keep it for the step it answers."""
        try:
            msg = read_motor_command(data, self.command_reader)
            u, saturated = command_vector(msg.name, msg.value, msg.mode, self.joint_names, self.mode, self.limit)
        except wire.DecodeError as exc:
            self.report("error", "malformed", f"motor_command rejected: {exc}")
            return
        except CommandError as exc:
            self.report("error", exc.kind, f"motor_command rejected: {exc}")
            return
        stamp_ns = msg.stamp_ns
        now_ns = self.sim.steps_taken * self.step_ns
        if self.config.stepping == "lockstep" and stamp_ns != now_ns:
            age = "stale" if stamp_ns < now_ns else "from the future"
            self.report(
                "error",
                age,
                f"motor_command rejected: stamp {stamp_ns * 1e-9:.6f} s is {age} (waiting for {now_ns * 1e-9:.6f} s)",
            )
            return
        if saturated:  # said only of a command that is applied
            self.warn_report("saturated", f"motor_command saturated to +/-{self.limit}")
        if self.config.stepping == "real_time":
            self.latest_command = (time.monotonic(), u)
        else:
            self.pending[stamp_ns] = u

    # -- publishing -----------------------------------------------------------------
    def publish_state(self, effort: Vector) -> None:
        t_ns = self.sim.steps_taken * self.step_ns
        position, velocity = self.sim.position, self.sim.velocity
        if self.sensors is None:
            self.joint_pub.publish(self.joint_wire.encode(t_ns, position, velocity, effort))
        else:  # once per state, in order: the velocity filter and the noise advance
            measured_position, measured_velocity = self.sensors.joints(position, velocity)
            self.joint_pub.publish(self.joint_wire.encode(t_ns, measured_position, measured_velocity, effort))
            self.truth_pubs[0].publish(self.joint_wire.encode(t_ns, position, velocity, effort))
        for pub in self.joint_command_pubs:  # the ros2_control face: the full truth, as a robot's driver gives it
            pub.publish(self.joint_wire.encode(t_ns, position, velocity, effort))
        self.clock_pub.publish(self.clock_wire.encode(t_ns))

    def publish_step(
        self, t_ns: int, command: Vector, d: Derivative, current: Vector, temperature: Vector, energy: Energy
    ) -> None:
        """Reports of one step: forces at its start under the held command, energies and the windings'
        temperatures up to its start."""
        terms = d.contacts
        active = d.active if d.active is not None else np.ones(terms.count, dtype=bool)
        reports = []
        wrench_pubs = self.wrench_pubs
        for j in range(terms.count):
            normal, friction = terms.normals[j], float(d.friction_force[j])
            normal_force = float(d.normal_force[j])
            if j < len(wrench_pubs):
                force = normal_force * normal + d.tangential_force[j]
                if self.sensors is not None:
                    force = self.sensors.force(force, normal)
                wrench_pubs[j].publish(self.wrench_wire.encode(t_ns, force))  # at the contact point: no moment
            reports.append(
                wire.ContactReport(
                    active=bool(active[j]),
                    position=terms.positions[j],
                    normal=normal,
                    normal_force=normal_force,
                    friction_force=friction,
                    slip_velocity=terms.slip_velocity[j],
                    residual=float(terms.residual[j]),
                )
            )
        self.contacts_pub.publish(self.contacts_wire.encode(t_ns, reports))
        if self.mode is InputMode.VOLTAGE:
            voltage, power = command, command * current
        else:  # direct drive: no circuit; mechanical power tau dq
            voltage, current, power = np.zeros(self.sim.n), np.zeros(self.sim.n), command * self.sim.velocity
        if not self.sim.dynamics.thermal:
            temperature = np.zeros(0)  # no thermal model: empty, not a made-up ambient
        energies = (energy.consumed, energy.net, energy.copper_loss)
        if self.sensors is None:
            self.motor_pub.publish(self.motor_wire.encode(t_ns, voltage, current, power, energies, temperature))
            return
        measured = self.sensors.currents(current) if self.mode is InputMode.VOLTAGE else current
        self.motor_pub.publish(self.motor_wire.encode(t_ns, voltage, measured, power, energies, temperature))
        self.truth_pubs[1].publish(self.motor_wire.encode(t_ns, voltage, current, power, energies, temperature))

    # -- one step -------------------------------------------------------------------
    def advance(self, command: Vector) -> bool:
        """Step with ``command`` held (or, with sensors.command_latency_steps, the answer that many
        states old), publish the new state, then the step's reports.

        The new state goes out first: the controller computes its answer while this
        process builds and sends the reports of the step just taken. A command whose step
        is not finite (the state, the energies, or the model at the new state: a finite but
        absurd value such as 1e300 V), or that takes a held contact further than
        divergence_residual off its surface, is refused: the step is taken back, nothing is
        published, ``refusal`` says why, and False is returned.
        """
        t_ns = self.sim.steps_taken * self.step_ns
        current, temperature, energy = self.sim.current, self.sim.temperature, self.sim.energy  # at the step's start
        checkpoint = self.sim.checkpoint()
        command = self.sensors.delay(command) if self.sensors is not None else command
        try:
            with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported as a refusal
                d = self.sim.step(command)
                residual = self.sim.check(self.config.divergence_speed, self.config.divergence_residual)
                effort = self.state_effort(command)
            if not _finite(effort):
                raise DivergenceError("non-finite forces or effort")
        except DivergenceError as exc:
            self.sim.restore(checkpoint)
            if self.sensors is not None:
                self.sensors.take_back()
            self.refusal = str(exc)
            return False
        self.command = command
        self.max_residual = max(self.max_residual, residual)
        self.publish_state(effort)
        self.publish_step(t_ns, command, d, current, temperature, energy)
        self.flow.sent()
        events = self.sim.events[self._events_logged :]
        for event in events:
            extra = f", {event.impact_loss:.4g} J lost in the impact" if event.kind == "touchdown" else ""
            if event.kind in ("stick", "slip"):  # Coulomb friction: frequent, and not news
                continue
            self.get_logger().info(f"contact {event.contact!r}: {event.kind} at t = {event.time:.6f} s{extra}")
        self._events_logged = len(self.sim.events)
        self.watch.events(events)
        self.watch_state(t_ns, d)
        now = time.monotonic()
        if now >= self._next_progress:
            self._next_progress = now + 0.5
            self.get_logger().info(f"progress t={self.sim.time:.3f} max_residual={self.max_residual:.3e}")
            self.status.say(RunStatus.PROGRESS, self.sim.time)
        return True

    def watch_state(self, t_ns: int, d: Derivative) -> None:
        """Give the watch the state a step's reports described (as ``contacts`` has it), and say its warnings."""
        terms = d.contacts
        active = d.active if d.active is not None else np.ones(terms.count, dtype=bool)
        self.say(self.watch.states([t_ns * 1e-9], active, d.normal_force, terms.residual))

    def refuse(self, command: Vector) -> None:
        """Say that ``command`` was refused because its step is not finite, naming its largest value."""
        j = int(np.argmax(np.abs(command)))
        unit = "V" if self.mode is InputMode.VOLTAGE else "N m"
        self.report(
            "error",
            "absurd",
            f"motor_command rejected: its step at t = {self.sim.time:.6f} s would not be finite "
            f"({self.joint_names[j]} = {command[j]:.6g} {unit}; {self.refusal}); the state is kept",
        )

    def state_effort(self, command: Vector | None = None) -> Vector:
        """JointState.effort under ``command`` (default: the held one): the link-side motor
        torque (the command itself in torque mode)."""
        command = self.command if command is None else command
        if self.mode is InputMode.TORQUE:
            return command
        return self.sim.evaluate(command).effort

    def done(self) -> bool:
        return self.total_steps is not None and self.sim.steps_taken >= self.total_steps

    def finish(self, command: Vector | None = None) -> None:
        """Report the final state (under ``command``, the answer to it if there is one, else
        the held command) and let reliable subscribers receive everything."""
        t_ns = self.sim.steps_taken * self.step_ns
        if command is not None and self.sensors is not None:
            command = self.sensors.delay(command)
        d = self.sim.evaluate(command) if command is not None else None
        if d is None or not _finite(d.normal_force, d.friction_force, d.effort):
            if command is not None:
                self.refusal = "non-finite forces or effort at the final state"
                self.refuse(command)
            d = self.sim.evaluate(self.command)
        else:
            self.command = command  # type: ignore[assignment]  # not None here
        self.publish_step(t_ns, self.command, d, self.sim.current, self.sim.temperature, self.sim.energy)
        self.watch_state(t_ns, d)
        self.say(self.watch.finish())  # on run_status before FINISHED: the recorder has them when it closes the bag
        self.flow.wait()  # every subscriber has every message before this process ends
        self.get_logger().info(f"progress t={self.sim.time:.3f} max_residual={self.max_residual:.3e}")
        self.get_logger().info(f"finished at t = {self.sim.time:.6f} s")
        self.status.say(RunStatus.FINISHED, self.sim.time, self.real_time_achieved)
        self.status.flush()  # bracing-pair has it before this process ends


def wait_for_recorder(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    """Before the first state: every report must reach the recorder, so it is matched on every
    topic (joint_states has the controller besides). AckWindow keeps it lossless from then on."""
    wait_until(
        node,
        executor,
        lambda: all(pub.get_subscription_count() >= 1 for pub in node.publishers_),
        "waiting for the recorder to subscribe to every topic",
    )


def wait_for_status_subscribers(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    """Before the first state: bracing-pair follows the run on run_status, and a run that ended
    before its subscriber matched would end unheard (measured: 1 of 12 runs of 0.01 s)."""
    wanted = node.config.min_status_subscribers
    wait_until(
        node,
        executor,
        lambda: node.status.subscribers() >= wanted,
        f"waiting for {wanted} subscriber(s) of run_status (bracing-pair)",
    )


def wait_for_ros2_control(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    """joint_commands: the first state goes out once min_subscribers listen on joint_states_topic and a
    publisher of joint_commands_topic is matched (a JointStateTopicSystem does both from its start)."""
    cfg = node.config
    wait_until(
        node,
        executor,
        lambda: (
            node.joint_command_pubs[0].get_subscription_count() >= cfg.min_subscribers
            and node.count_publishers(cfg.joint_commands_topic) >= 1
        ),
        f"waiting for {cfg.min_subscribers} subscriber(s) of {cfg.joint_states_topic} and a publisher of "
        f"{cfg.joint_commands_topic} (start the ros2_control side)",
    )


def spin_lockstep(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    cfg = node.config
    since = time.monotonic()
    # Wait for the controller (and a recorder, if asked) before the first state. The publishers'
    # matched events wake the executor, so the first step follows the last match at once.
    wait_until(
        node,
        executor,
        lambda: (
            node.joint_pub.get_subscription_count() >= cfg.min_subscribers
            # and the controller's motor_command writer, or its first answer may be lost to this reader
            and (cfg.min_subscribers == 0 or node.command_sub is None or node.command_sub.get_publisher_count() >= 1)
        ),
        f"lockstep: waiting for {cfg.min_subscribers} subscriber(s) of joint_states and a publisher of "
        "motor_command (start the controller)",
    )
    if cfg.wait_for_recorder:
        wait_for_recorder(node, executor)
    wait_for_status_subscribers(node, executor)
    node.get_logger().info(f"lockstep: stepping (subscribers matched in {time.monotonic() - since:.3f} s)")
    node.status.say(RunStatus.STEPPING, node.sim.time)
    assert node.command_sub is not None  # lockstep: motor_command (joint_commands does not lockstep)
    waiter = SubscriptionWaiter(node, node.command_sub)
    node.publish_state(node.state_effort())
    node.flow.sent()
    while not node.done():
        step_lockstep(node, waiter, executor)
    # The answer to the final state, for its reports.
    deadline = time.monotonic() + cfg.command_timeout
    node.finish(next_command(node, waiter, deadline))


def next_command(node: SimulatorNode, waiter: SubscriptionWaiter, deadline: float) -> Vector | None:
    """The next valid command stamped with the current state's stamp, or None at ``deadline``."""
    expected = node.sim.steps_taken * node.step_ns
    while expected not in node.pending:
        remaining = deadline - time.monotonic()
        if remaining <= 0.0:
            return None
        for msg in waiter.take(min(remaining, 0.1)):
            node.on_command(msg)
    command = node.pending.pop(expected)
    node.pending.clear()
    return command


def step_lockstep(node: SimulatorNode, waiter: SubscriptionWaiter, executor: SingleThreadedExecutor) -> None:
    """One step with the answer to the current state: the first valid command stamped with its
    stamp whose step is finite; the watchdog's choice if none comes within command_timeout.
    Raises DivergenceError if even that step is not finite (the model, not the input)."""
    cfg = node.config
    if node.sim.steps_taken % 100 == 0:
        executor.spin_once(timeout_sec=0.0)  # parameter services and the like
    deadline = time.monotonic() + cfg.command_timeout
    while (command := next_command(node, waiter, deadline)) is not None:
        if node.advance(command):
            return
        node.refuse(command)
    fallback = watchdog_command(node)
    if not node.advance(fallback):
        raise DivergenceError(f"{node.refusal} (under the watchdog's command: {cfg.watchdog_policy})")


def watchdog_command(node: SimulatorNode) -> Vector:
    """What the watchdog applies when no valid command came in time, after saying so."""
    cfg = node.config
    expected = node.sim.steps_taken * node.step_ns
    policy = cfg.watchdog_policy
    node.warn_report(
        "watchdog",
        f"no valid motor_command for t = {expected * 1e-9:.6f} s within {cfg.command_timeout} s: "
        f"{'holding the last command' if policy == 'hold' else 'applying zero'}",
    )
    return node.command if policy == "hold" else np.zeros(node.sim.n)


def spin_real_time(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    cfg = node.config
    period = cfg.step / cfg.real_time_factor

    def tick() -> None:
        if node.done():
            return
        latest = node.latest_command
        if latest is None or time.monotonic() - latest[0] > cfg.command_timeout:
            if latest is not None:
                source = "motor_command" if cfg.command_source == "motor_command" else cfg.joint_commands_topic
                node.warn_report("watchdog", f"{source} stale: applying zero")
            request = np.zeros(node.sim.n)
        else:
            request = latest[1]
        command = node.applied(request)
        if node.advance(command):
            if node.drive is not None:
                node.drive.commit()
            return
        node.refuse(command)
        node.latest_command = None  # never again: a stale command becomes zero
        if not node.advance(node.applied(np.zeros(node.sim.n))):
            raise DivergenceError(f"{node.refusal} (under a zero command)")
        if node.drive is not None:
            node.drive.commit()

    wait_for_status_subscribers(node, executor)
    if node.joint_command_pubs:
        wait_for_ros2_control(node, executor)
    free = cfg.stepping == "free_run"
    node.get_logger().info("free run: stepping as fast as it can" if free else "real-time: stepping")
    node.status.say(RunStatus.STEPPING, node.sim.time)
    node.publish_state(node.state_effort())
    started = time.monotonic()
    if free:  # as fast as it can; /clock tells use_sim_time nodes the time
        while not node.done():
            executor.spin_once(timeout_sec=0.0)
            tick()
    else:
        node.create_timer(period, tick)
        while not node.done():
            executor.spin_once(timeout_sec=0.1)
    report_real_time(node, time.monotonic() - started)
    node.finish()


def report_real_time(node: SimulatorNode, wall_s: float) -> None:
    """Say how fast real-time stepping went (in the log, and to bracing-pair in the FINISHED status),
    and warn if it fell behind: a timer whose ticks run late skips them, so the sim time lags the wall clock."""
    achieved = node.sim.time / wall_s if wall_s > 0.0 else float("inf")
    node.real_time_achieved = achieved
    asked = node.config.real_time_factor
    node.get_logger().info(f"{REAL_TIME_ACHIEVED}{achieved:.4f}x real time (asked {asked:g}x)")
    if node.config.stepping == "real_time":  # free_run asks for no pace
        node.say(node.watch.real_time(achieved, asked))


def _finite(*arrays: Vector) -> bool:
    return all(bool(np.isfinite(a).all()) for a in arrays)


def spin(node: SimulatorNode) -> int:
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        if node.config.stepping == "lockstep":
            spin_lockstep(node, executor)
        else:
            spin_real_time(node, executor)
    except DivergenceError as exc:
        node.get_logger().fatal(f"simulation diverged at t = {node.sim.time:.6f} s: {exc}")
        print(f"error: simulation diverged at t = {node.sim.time:.6f} s: {exc}", file=sys.stderr, flush=True)
        return EXIT_DIVERGED
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    return 0


def main(args: list[str] | None = None) -> int:
    code = run(SimulatorNode, spin, args)  # type: ignore[arg-type]
    sys.exit(code)


if __name__ == "__main__":
    main()
