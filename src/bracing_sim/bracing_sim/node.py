"""bracing-simulator: publishes the simulated robot, applies motor commands.

Thin: ROS parameters -> SimulatorConfig -> core Simulator; messages in and out.
Lockstep (default): publish state k, wait for the command stamped with state k's
stamp, step with it held. Real-time: a wall-clock timer steps with the latest command.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from bracing_msgs.msg import Contacts, MotorCommand, MotorState
from bracing_sim import wire
from bracing_sim.commands import MODE_CODES, CommandError, command_vector
from bracing_sim.config import SimulatorConfig, build_simulator
from bracing_sim.core.dynamics import Derivative, InputMode
from bracing_sim.core.simulator import DivergenceError, Energy
from bracing_sim.core.types import Vector
from bracing_sim.ros_common import (
    EXIT_DIVERGED,
    STREAM_QOS,
    SUBSCRIBE_QOS,
    RateLimitedLog,
    SubscriptionWaiter,
    read_motor_command,
    read_parameters,
    run,
)


class SimulatorNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_simulator", **kwargs)  # type: ignore[arg-type]
        self.config = SimulatorConfig.from_params(read_parameters(self))
        self.plant, self.sim = build_simulator(self.config)
        self.joint_names = list(self.plant.joint_names)
        self.mode = self.config.shared.input_mode
        motors = self.plant.motors
        self.limit = motors.voltage_limit if self.mode is InputMode.VOLTAGE else motors.torque_limit
        self.step_ns = round(self.config.step * 1e9)
        duration = self.config.duration
        self.total_steps = round(duration / self.config.step) if duration > 0 else None

        self.joint_pub = self.create_publisher(JointState, "joint_states", STREAM_QOS)
        self.contacts_pub = self.create_publisher(Contacts, "contacts", STREAM_QOS)
        self.motor_pub = self.create_publisher(MotorState, "motor_state", STREAM_QOS)
        self.clock_pub = self.create_publisher(Clock, "/clock", STREAM_QOS)
        self.wrench_pubs = [
            self.create_publisher(WrenchStamped, f"contact_wrench/{c.name}", STREAM_QOS)
            for c in self.config.shared.contacts
        ]
        # Messages travel as CDR bytes built by ``wire`` (rclpy's message classes cost more than the DDS write).
        contacts = self.config.shared.contacts
        self.joint_wire = wire.JointStateEncoder(self.joint_names)
        self.clock_wire = wire.ClockEncoder()
        self.wrench_wire = wire.WrenchStampedEncoder("world")
        self.contacts_wire = wire.ContactsEncoder([c.name for c in contacts], [c.frame for c in contacts])
        self.motor_wire = wire.MotorStateEncoder(self.joint_names)
        self.command_reader = wire.MotorCommandDecoder(self.joint_names, MODE_CODES[self.mode])
        self.command_sub = self.create_subscription(
            MotorCommand, "motor_command", self._on_command, SUBSCRIBE_QOS, raw=True
        )
        self.report = RateLimitedLog(self)

        self.command = np.zeros(self.sim.n)  # last applied (held) command
        self._pending: dict[int, Vector] = {}  # lockstep: valid commands by stamp [ns]
        self._latest: tuple[float, Vector] | None = None  # real-time: (wall time, command)
        self._next_progress = 0.0  # wall time of the next progress line
        self.max_residual = 0.0  # [m], over the run so far (contacts holding a force)
        self._events_logged = 0
        self.get_logger().info(
            f"{self.mode.value} input, {len(self.plant.contact_set)} contact(s), step {self.config.step} s, "
            f"{self.config.stepping}, duration {duration or 'unbounded'} s"
        )

    # -- commands -------------------------------------------------------------------
    def _on_command(self, data: bytes) -> None:
        try:
            msg = read_motor_command(data, self.command_reader)
            u, saturated = command_vector(msg.name, msg.value, msg.mode, self.joint_names, self.mode, self.limit)
        except wire.DecodeError as exc:
            self.report("error", "malformed", f"motor_command rejected: {exc}")
            return
        except CommandError as exc:
            self.report("error", exc.kind, f"motor_command rejected: {exc}")
            return
        if saturated:
            self.report("warning", "saturated", f"motor_command saturated to +/-{self.limit}")
        stamp_ns = msg.stamp_ns
        if self.config.stepping == "real_time":
            self._latest = (time.monotonic(), u)
            return
        now_ns = self.sim.steps_taken * self.step_ns
        if stamp_ns != now_ns:
            age = "stale" if stamp_ns < now_ns else "from the future"
            self.report(
                "error",
                age,
                f"motor_command rejected: stamp {stamp_ns * 1e-9:.6f} s is {age} (waiting for {now_ns * 1e-9:.6f} s)",
            )
            return
        self._pending[stamp_ns] = u

    # -- publishing -----------------------------------------------------------------
    def publish_state(self, effort: Vector) -> None:
        t_ns = self.sim.steps_taken * self.step_ns
        self.joint_pub.publish(self.joint_wire.encode(t_ns, self.sim.position, self.sim.velocity, effort))
        self.clock_pub.publish(self.clock_wire.encode(t_ns))

    def publish_step(self, t_ns: int, command: Vector, d: Derivative, current: Vector, energy: Energy) -> None:
        """Reports of one step: forces at its start under the held command, energies up to its start."""
        terms = d.contacts
        active = d.active if d.active is not None else np.ones(terms.count, dtype=bool)
        reports = []
        for j in range(len(self.wrench_pubs)):
            normal, friction = terms.normals[j], float(d.friction_force[j])
            normal_force = float(d.normal_force[j])
            force = normal_force * normal - friction * terms.slip_direction[j]
            self.wrench_pubs[j].publish(self.wrench_wire.encode(t_ns, force))  # at the contact point: no moment
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
        energies = (energy.consumed, energy.net, energy.copper_loss)
        self.motor_pub.publish(self.motor_wire.encode(t_ns, voltage, current, power, energies))

    # -- one step -------------------------------------------------------------------
    def advance(self, command: Vector) -> None:
        """Step with ``command`` held, publish the new state, then the step's reports.

        The new state goes out first: the controller computes its answer while this
        process builds and sends the reports of the step just taken.
        """
        t_ns = self.sim.steps_taken * self.step_ns
        current, energy = self.sim.current, self.sim.energy  # at the step's start
        d = self.sim.step(command)
        self.command = command
        held = d.contacts.residual if d.active is None else d.contacts.residual[d.active]
        residual = float(np.max(np.abs(held))) if held.size else 0.0
        self.max_residual = max(self.max_residual, residual)
        if residual > self.config.divergence_residual:
            self.publish_step(t_ns, command, d, current, energy)  # the bag shows the step that failed
            raise DivergenceError(
                f"constraint residual {residual:.3g} m exceeds divergence_residual {self.config.divergence_residual} m"
            )
        self.publish_state(self.state_effort())
        self.publish_step(t_ns, command, d, current, energy)
        for event in self.sim.events[self._events_logged :]:
            extra = f", {event.impact_loss:.4g} J lost in the impact" if event.kind == "touchdown" else ""
            self.get_logger().info(f"contact {event.contact!r}: {event.kind} at t = {event.time:.6f} s{extra}")
        self._events_logged = len(self.sim.events)
        now = time.monotonic()
        if now >= self._next_progress:  # bracing-pair follows these lines
            self._next_progress = now + 0.5
            self.get_logger().info(f"progress t={self.sim.time:.3f} max_residual={self.max_residual:.3e}")

    def state_effort(self) -> Vector:
        """JointState.effort: link-side motor torque (the held command in torque mode)."""
        if self.mode is InputMode.TORQUE:
            return self.command
        return self.sim.evaluate(self.command).effort

    def done(self) -> bool:
        return self.total_steps is not None and self.sim.steps_taken >= self.total_steps

    def finish(self, command: Vector | None = None) -> None:
        """Report the final state (under ``command``, the answer to it if there is one, else
        the held command) and let reliable subscribers receive everything."""
        t_ns = self.sim.steps_taken * self.step_ns
        if command is not None:
            self.command = command
        d = self.sim.evaluate(self.command)
        self.publish_step(t_ns, self.command, d, self.sim.current, self.sim.energy)
        deadline = time.monotonic() + 10.0  # one budget for all: a loaded machine may need it
        for pub in (self.joint_pub, self.contacts_pub, self.motor_pub, self.clock_pub, *self.wrench_pubs):
            pub.wait_for_all_acked(Duration(seconds=max(deadline - time.monotonic(), 0.1)))
        self.get_logger().info(f"progress t={self.sim.time:.3f} max_residual={self.max_residual:.3e}")
        self.get_logger().info(f"finished at t = {self.sim.time:.6f} s")


def spin_lockstep(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    cfg = node.config
    # Wait for the controller (and a recorder, if asked) before the first state.
    since, told = time.monotonic(), False
    while node.joint_pub.get_subscription_count() < cfg.min_subscribers:
        executor.spin_once(timeout_sec=0.05)
        if not told and time.monotonic() - since > 2.0:
            told = True
            node.get_logger().info(
                f"lockstep: waiting for {cfg.min_subscribers} subscriber(s) of joint_states (start the controller)"
            )
    waiter = SubscriptionWaiter(node, node.command_sub)
    node.publish_state(node.state_effort())
    while not node.done():
        node.advance(wait_for_command(node, waiter, executor))
    node.finish(wait_for_command(node, waiter, executor))  # the answer to the final state, for its reports


def wait_for_command(node: SimulatorNode, waiter: SubscriptionWaiter, executor: SingleThreadedExecutor) -> Vector:
    """The valid command stamped with the current state's stamp; the watchdog's choice if
    none comes within command_timeout."""
    cfg = node.config
    expected = node.sim.steps_taken * node.step_ns
    deadline = time.monotonic() + cfg.command_timeout
    if node.sim.steps_taken % 100 == 0:
        executor.spin_once(timeout_sec=0.0)  # parameter services and the like
    while expected not in node._pending:
        remaining = deadline - time.monotonic()
        if remaining <= 0.0:
            break
        for msg in waiter.take(min(remaining, 0.1)):
            node._on_command(msg)
    command = node._pending.pop(expected, None)
    node._pending.clear()
    if command is not None:
        return command
    policy = cfg.watchdog_policy
    node.report(
        "warning",
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
        latest = node._latest
        if latest is None or time.monotonic() - latest[0] > cfg.command_timeout:
            if latest is not None:
                node.report("warning", "watchdog", "motor_command stale: applying zero")
            command = np.zeros(node.sim.n)
        else:
            command = latest[1]
        node.advance(command)

    node.publish_state(node.state_effort())
    node.create_timer(period, tick)
    while not node.done():
        executor.spin_once(timeout_sec=0.1)
    node.finish()


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
