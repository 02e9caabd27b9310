"""The controller node's policy, without ROS: how one joint state becomes the law's answer.

Per state: a joint state that cannot be answered (larger than ``MessageLimits``, lengths, a joint
missing, not finite, a stamp out of ``builtin_interfaces/Time``) is refused with a report rate-limited
by its kind; a retune takes effect; the force
and temperature reports of the step before wait briefly (``Measurements``, ``MEASUREMENT_WAIT_S``); the
targets that came are fed to the law (``TaskTargets``); the law's failure or a non-finite output
refuses the state; a damped inverse is reported; every ``NULL_SPACE_CHECK_EVERY`` states the null
space's speed is looked at, and a runaway said once (log and run_status). What it says goes through a
``NodeLog``; the messages that come in while it waits are taken by an injected ``receive``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

import bracing_engine as engine
from bracing_core import run_parameters
from bracing_core.checks import configuration_warnings, desired_force_warning, frame_reach, null_space_warning
from bracing_core.controller_config import ControllerConfig
from bracing_core.dynamics import ConstrainedDynamics, reflected_terms
from bracing_core.kinematics import WORLD_FRAME
from bracing_core.law import DecoupledController
from bracing_core.measurements import Measurements
from bracing_core.message_limits import DEFAULT_LIMITS, MessageLimits, SizeError, quote_names
from bracing_core.mobile_base import BaseDrive, CmdVelRefused, keep_contact_force
from bracing_core.node_log import NodeLog, Refusal
from bracing_core.numbers import all_finite
from bracing_core.params import ConfigError
from bracing_core.targets import OrientationSpec, TargetLimits, TaskSpec, TaskTargets
from bracing_core.types import HAND_TASK, Vector, brace_task

NULL_SPACE_CHECK_EVERY = 20
"""States between two looks at the null space's speed (1 us each in the engine; a runaway lasts 100s of steps)."""
MEASUREMENT_WAIT_S = 0.5
"""[s] wall: how long a state waits for the force and temperature reports of the step before it
(``Measurements``); past it the state is answered with the latest ones, and a warning says which lagged."""


class StateError(Refusal):
    """A joint_states message the controller cannot use."""


def joint_vectors(
    names: list[str],
    position: Vector,
    velocity: Vector,
    stamp_ns: int,
    joint_names: list[str],
    limits: MessageLimits = DEFAULT_LIMITS,
) -> tuple[Vector, Vector]:
    """(q, dq) in ``joint_names`` order from a joint state's joints matched by name; sizes checked first,
    then every check linear in the names."""
    try:
        limits.check_count("name", len(names))
        limits.check_count("position", len(position))
        limits.check_count("velocity", len(velocity))
    except SizeError as exc:
        raise StateError(exc.kind, str(exc)) from None
    if len(position) != len(names) or len(velocity) != len(names):
        raise StateError("length", f"{len(names)} names, {len(position)} positions, {len(velocity)} velocities")
    if names == joint_names:  # the simulator's order: nothing to match
        q, dq = position, velocity
    else:
        try:
            limits.check_name("name", max(names, key=len, default=""))
        except SizeError as exc:
            raise StateError(exc.kind, str(exc)) from None
        if len(set(names)) != len(names):
            raise StateError("duplicate", "duplicate joint names")
        index = {name: k for k, name in enumerate(names)}
        missing = [j for j in joint_names if j not in index]
        if missing:
            raise StateError("missing", f"missing joints {quote_names(missing)}")
        order = [index[j] for j in joint_names]
        q, dq = position[order], velocity[order]
    # finite, a stamp in builtin_interfaces/Time's range: the engine's check, which the rcl path makes too
    refused = engine.state_refusal(stamp_ns, np.asarray(q, dtype=float), np.asarray(dq, dtype=float))
    if refused is not None:
        raise StateError(*refused)
    return q, dq


def orientation_retune_refusal(config: ControllerConfig, retuned: ControllerConfig) -> str | None:
    """Why hand.orientation.target cannot change so while running (None: it can): emptied (there is no first
    measured orientation to go back to), or set without an orientation task."""
    before, after = config.orientation.target, retuned.orientation.target
    if after == before:
        return None
    if after is None:
        return "hand.orientation.target: cannot be emptied while running (set the orientation to hold instead)"
    if not retuned.orientation.axes:
        return "hand.orientation.target: no orientation task to turn (set hand.orientation.axes before the run)"
    return None


def task_targets(law: DecoupledController) -> TaskTargets:
    """The targets of the law's tasks (the hand, then each braced contact), with their reach."""
    config, plant = law.config, law.plant
    specs = [
        TaskSpec(
            "hand_target",
            config.hand_task.axes,
            frame_reach(plant.robot.model, plant.frame_id(config.hand.frame, "hand.frame")),
        )
    ]
    for c in config.shared.braced_contacts:
        reach = frame_reach(plant.robot.model, plant.frame_id(c.frame, f"contacts.{c.name}.frame"))
        specs.append(TaskSpec(f"brace_target/{c.name}", c.brace_axes, reach))
    limits = TargetLimits(config.max_message_elements, config.max_name_length, config.targets.max_horizon)
    orientation = OrientationSpec(
        config.orientation.axes, config.targets.max_angular_velocity, config.targets.max_angular_acceleration
    )
    return TaskTargets(specs, config.targets.max_velocity, config.targets.max_acceleration, limits, orientation)


@dataclass(frozen=True)
class Answer:
    """The law's answer to the state stamped ``stamp_ns`` (motor_command and controller_state)."""

    stamp_ns: int
    output: engine.LawOutput
    desired_normal_force: Vector  # (b,) f_nd [N] the law answered with (a copy: a retune changes the law's)
    compute_time: float  # [s] wall, the law's update


class StateAnswerer:
    """The controller node's policy (see the module docstring). ``clock``: wall time [s], monotonic;
    ``timer``: what the law's compute time is measured with."""

    def __init__(
        self,
        config: ControllerConfig,
        log: NodeLog,
        clock: Callable[[], float] = time.monotonic,
        timer: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.log, self.clock, self.timer = log, clock, timer
        self.previous_ns: int | None = None  # the stamp of the last state answered (None: none yet)
        self.null_space_warned = False
        self.answers = 0  # states answered (the null-space watch samples them)
        self.rebuild(config)

    def rebuild(self, config: ControllerConfig) -> None:
        """What ``config`` gives the answering: the law, its targets, measurements and base drive, as a fresh
        process builds them (``__init__``; and a run built anew from changed per-run parameters, whose first state,
        back in time, then starts it: ``restart``)."""
        self.config = config
        self.law = DecoupledController(config)
        self.joint_names = list(self.law.plant.joint_names)
        self.limits = MessageLimits.of(config)  # what one subscribed message may carry
        self.measurements = Measurements.for_law(self.law)  # None: the law reads no measurement
        self.targets = task_targets(self.law)
        self.retuned: ControllerConfig | None = None  # applied at the next update
        self.base_drive = self.new_base_drive()  # base_command cmd_vel: the base follows cmd_vel (None: not)
        if self.base_drive is not None:
            plant = self.law.plant  # the law's model: J_c and Mc for B = J_c Mc^-1
            self.braced = ConstrainedDynamics(plant.robot, plant.motors, self.law.contact_set, plant.mode)

    def new_base_drive(self) -> BaseDrive | None:
        """base_command cmd_vel: the base's velocity loop as at a run's start (None: the law moves the base)."""
        config = self.config
        if config.base_command != "cmd_vel":
            return None
        wheels = config.shared.wheels if config.shared.base == "diff_drive" else None
        return BaseDrive(
            self.joint_names, config.cmd_vel_timeout, config.base_velocity_kd, wheels, config.base_velocity_ki
        )

    def restart(self, stamp_ns: int) -> None:
        """A state stamped before the last one answered: the simulator went back in time (its reset_simulation),
        so a new run starts at this state, with the parameters as they are now. The law forgets its first
        measured targets and its integrals; each task's reference starts again from its configured path (a goal
        that came by topic is kept, followed again from this state); the run before's measurements, cmd_vel and
        warnings are forgotten."""
        self.log.info(
            f"joint_states went back in time, from t = {engine.stamp_seconds(self.answered_ns):.6f} s to "
            f"{engine.stamp_seconds(stamp_ns):.6f} s: a new run (the law's integrals and first targets reset)"
        )
        self.law.reset()
        self.targets.restart()
        self.measurements = Measurements.for_law(self.law)
        self.base_drive = self.new_base_drive()
        self.previous_ns = None
        self.null_space_warned = False
        self.answers = 0

    def goes_back(self, stamp_ns: int) -> bool:
        """Whether a state stamped ``stamp_ns`` is earlier than the last one answered: a new run (``restart``)."""
        return self.previous_ns is not None and stamp_ns < self.previous_ns

    @property
    def answered_ns(self) -> int:
        """[ns] the stamp of the last state answered (0 before the first)."""
        return 0 if self.previous_ns is None else self.previous_ns

    def start(self) -> None:
        """Say what the law does, and what looks wrong in its configuration (once, before the run)."""
        contacts = [c.name for c in self.config.shared.braced_contacts]
        self.log.info(
            f"{self.config.shared.input_mode.value} output, contacts {contacts or 'none'}, "
            f"task dimension {self.config.task_dimension}"
        )
        for warning in configuration_warnings(self.config, self.law.plant):
            self.log.warning(warning)

    # -- parameters -------------------------------------------------------------------
    def retune(self, params: dict[str, Any], changes: Sequence[tuple[str, Any]]) -> str | None:
        """Tunable parameters changed (``params``: all of them as they are, by flat name; ``changes``: (name,
        value)): validated as a whole configuration, applied from the next update, logged. Why not, if refused."""
        reason = run_parameters.refusal("controller", [name for name, _ in changes])
        if reason is not None:
            return reason
        for name, value in changes:
            if not run_parameters.takes_live("controller", name):
                return f"{name}: cannot change before the next run (a per-run parameter)"
            params[name] = value
        params["robot.urdf"] = str(self.config.shared.urdf)  # as the node resolved it
        try:
            config = ControllerConfig.from_params(params)
        except ConfigError as exc:
            return str(exc)
        refused = orientation_retune_refusal(self.config, config)
        if refused is not None:
            return refused
        self.retuned = config
        self.log.info("retuned (from the next update): " + ", ".join(f"{name} = {value}" for name, value in changes))
        changed = {name for name, _ in changes}
        for contact in config.shared.braced_contacts:
            if f"contacts.{contact.name}.desired_normal_force" in changed:
                t = engine.stamp_seconds(self.answered_ns)
                warning = desired_force_warning(contact.name, contact.desired_normal_force or 0.0, t)
                if warning is not None:
                    self.log.warning(warning)
        return None

    # -- measurements -----------------------------------------------------------------
    def take_force(self, contact: str, stamp_ns: int, force: Vector, frame: str = WORLD_FRAME) -> None:
        """A contact's measured force (contact_wrench/<contact>), kept unless refused."""
        assert self.measurements is not None
        problem = self.measurements.take_force(contact, stamp_ns, force, frame)
        if problem is not None:
            self.log.limited("error", "measurement", f"ignored: {problem}")

    def take_temperature(self, stamp_ns: int, temperature: Vector) -> None:
        """The windings' measured temperatures (motor_state), kept unless refused."""
        assert self.measurements is not None
        problem = self.measurements.take_temperature(stamp_ns, temperature, len(self.joint_names))
        if problem is not None:
            self.log.limited("error", "measurement", f"ignored: {problem}")

    def measure(self, receive: Callable[[float], None]) -> None:
        """Give the law the reports of the step before this state, waiting briefly for them.
        ``receive(timeout)`` takes the reports that come within ``timeout`` [s] (to ``take_*``)."""
        measurements = self.measurements
        if measurements is None:
            return
        deadline = self.clock() + MEASUREMENT_WAIT_S
        receive(0.0)
        while not measurements.ready(self.previous_ns) and (left := deadline - self.clock()) > 0.0:
            receive(min(left, 0.05))
        if self.previous_ns is not None and not measurements.ready(self.previous_ns):
            lagging = ", ".join(measurements.missing(self.previous_ns))
            message = f"no report of the last step within {MEASUREMENT_WAIT_S} s: {lagging}"
            self.log.limited("warning", "lagging", message)
        measurements.apply(self.law)

    # -- one state ----------------------------------------------------------------------
    def read_state(
        self, names: list[str], position: Vector, velocity: Vector, stamp_ns: int, refusal: tuple[str, str, str]
    ) -> tuple[Vector, Vector] | None:
        """(q, dq) of a joint state in the law's joint order, or None after reporting why it cannot be
        answered; ``refusal``: (severity, verdict, what follows), e.g. ("error", "ignored", "")."""
        try:
            return joint_vectors(names, position, velocity, stamp_ns, self.joint_names, self.limits)
        except StateError as exc:
            severity, verdict, then = refusal
            self.log.limited(severity, exc.kind, f"joint_states {verdict}: {exc}{then}")
            return None

    def answer(
        self, stamp_ns: int, q: Vector, dq: Vector, receive: Callable[[float], None], send: Callable[[Answer], None]
    ) -> None:
        """The law's answer to the state (q, dq) stamped ``stamp_ns``, to ``send`` (the node's publishers),
        unless the law fails on it or its output is not finite (then nothing is sent)."""
        if self.goes_back(stamp_ns):
            self.restart(stamp_ns)
        if self.retuned is not None:
            self.law.retune(self.retuned)
            target = self.retuned.orientation.target
            if target != self.config.orientation.target and target is not None:  # turned to, as a pose's
                self.targets.turn_to(target)
            self.config, self.retuned = self.retuned, None
        t = engine.stamp_seconds(stamp_ns)  # the rollout's conversion: the same law's time, bit for bit
        self.measure(receive)
        self.follow_targets(t)
        self.carry_paths(t, q, dq)
        start = self.timer()
        try:
            out = self.law.update(t, q, dq)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:  # absurd but finite q, dq
            self.law_failed(stamp_ns, str(exc))
            return
        self.drive_base(stamp_ns, q, dq, out)
        compute_time = self.timer() - start
        desired_normal_force = self.law.desired_normal_force.copy()
        outputs = (out.command, out.hand_desired, out.hand_actual, desired_normal_force)
        if not all_finite(*outputs, out.brace_desired, out.brace_actual):
            self.output_not_finite(stamp_ns)
            return
        self.answered(stamp_ns, out.damped, lambda: (out.hand_desired, out.hand_actual, dq))
        send(Answer(stamp_ns, out, desired_normal_force, compute_time))
        self.previous_ns = stamp_ns

    def answered(self, stamp_ns: int, damped: bool, sample: Callable[[], tuple[Vector, Vector, Vector]]) -> None:
        """What follows an answer to the state stamped ``stamp_ns``, before it is sent: a damped inverse said, the
        null space watched (``sample``: the hand's desired and actual position and dq, when looked at)."""
        if damped:
            self.log.limited("warning", "damped", "B is near-singular: using a damped inverse")
        self.watch_null_space(sample, engine.stamp_seconds(stamp_ns))

    def law_failed(self, stamp_ns: int, error: str) -> None:
        """The law raised ``error`` (ValueError or ArithmeticError) on the state stamped ``stamp_ns``: ignored."""
        t = engine.stamp_seconds(stamp_ns)
        self.log.limited("error", "law", f"joint_states at t = {t:.6f} s ignored: the law failed on it ({error})")

    def output_not_finite(self, stamp_ns: int) -> None:
        """The law's answer to the state stamped ``stamp_ns`` is not finite: ignored."""
        message = f"joint_states at t = {engine.stamp_seconds(stamp_ns):.6f} s ignored: the law's output is not finite"
        self.log.limited("error", "command", message)

    @property
    def law_only(self) -> bool:
        """Whether the next state needs the law alone: no retune waiting, no measurement, no target followed
        and no base driven (what the controller's rcl path answers by itself)."""
        targets = self.targets
        return (
            self.retuned is None
            and self.measurements is None
            and self.base_drive is None
            and not targets.goals
            and targets.orientation_goal is None
        )

    def follow_targets(self, t: float) -> None:
        """Feed the law each retargeted task's reference at t (hand_target, hand_path, brace_target/<contact>,
        hand_pose_target: its orientation too)."""
        targets = self.targets
        if not (targets.goals or targets.orientation_goal is not None) or self.previous_ns is None:
            return  # no target, or the law has no path start yet
        engine = self.law.engine
        for task, (position, velocity) in self.targets.advance(t, engine.path_sample).items():
            engine.set_reference(task, position, velocity)
        turn = self.targets.advance_orientation(t, engine.orientation_reference)
        if turn is not None:
            engine.set_orientation_reference(*turn)

    # -- a mobile base following cmd_vel ----------------------------------------------------
    def take_cmd_vel(self, stamp_ns: int, linear: Sequence[float], angular: Sequence[float]) -> None:
        """A cmd_vel (TwistStamped: its stamp, linear and angular), kept unless refused (on the node's clock: the
        sim time of the last state answered)."""
        if self.base_drive is None:
            self.log.limited("warning", "cmd_vel", "cmd_vel ignored: base_command is task (set it to cmd_vel)")
            return
        try:
            self.base_drive.gate.offer(stamp_ns, linear, angular, self.answered_ns)
        except CmdVelRefused as exc:
            self.log.limited("warning", exc.kind, f"cmd_vel ignored: {exc}")

    def carry_paths(self, t: float, q: Vector, dq: Vector) -> None:
        """base_command cmd_vel: each task's configured path (not one a target topic retargets), carried with
        the base."""
        drive = self.base_drive
        if drive is None or self.previous_ns is None:  # the paths start at the first state
            return
        engine = self.law.engine
        braces = range(len(self.config.shared.braced_contacts))
        tasks = [k for k in (HAND_TASK, *map(brace_task, braces)) if k not in self.targets.goals]
        carried = drive.targets(q, dq, [engine.path_sample(k, t) for k in tasks])
        for task, (position, velocity) in zip(tasks, carried, strict=True):
            engine.set_reference(task, position, velocity)

    def drive_base(self, stamp_ns: int, q: Vector, dq: Vector, out: engine.LawOutput) -> None:
        """base_command cmd_vel: the base actuators' velocity loop added to the law's command on them, the arm
        taking up what it would lean on the braces (``keep_contact_force``)."""
        drive = self.base_drive
        if drive is None:
            return
        if self.previous_ns is None:
            drive.targets(q, dq, [])  # the base's pose at the start: the paths' frame
        was_braking = drive.gate.braking
        tau = drive.torques(stamp_ns, q, dq)
        if drive.gate.braking and not was_braking:
            self.log.warning(f"cmd_vel timed out at t = {stamp_ns * 1e-9:.6f} s: braking (zero velocity)")
        joints = drive.actuators
        torque = keep_contact_force(self.contact_map(q, dq), out.torque, joints, out.torque[joints] + tau)
        if self.config.shared.input_mode.value == "voltage":  # eq. 41 on the change
            out.command = out.command + self.law.plant.to_model_order(self.config.voltage_gain) * (torque - out.torque)
        else:
            out.command = torque
        out.torque = torque

    def contact_map(self, q: Vector, dq: Vector) -> Vector:
        """B = J_c Mc^-1 (p x n) of the law's model at (q, dq) (eq. 36): how joint torques reach the braces'
        normal accelerations; Mc = M (pinocchio's crba) + the reflected rotor inertia in voltage mode. On a
        differential drive, B of the rolling system: J_c T (T^T Mc T)^-1 (T^T tau = tau off the base, whose
        joints have no torque), T the law's map from the admissible motions (``motion_map``: the engine's rolling
        rows), the base's block of T^T Mc T set to I as the law sets it (its columns of B are zero)."""
        robot = self.law.plant.robot
        position = np.asarray(q, dtype=float)
        mass = pin.crba(robot.model, robot.data, position)
        mass = np.triu(mass) + np.triu(mass, 1).T
        mass += np.diag(reflected_terms(robot, self.law.plant.motors, self.law.plant.mode)[0])
        normal = self.braced.terms(q, dq).normal_jacobian
        if self.base_drive is None or self.base_drive.wheels is None:
            return np.linalg.solve(mass, normal.T).T
        motion = np.asarray(self.law.engine.motion_map(position))
        reduced = motion.T @ mass @ motion
        reduced[:3, :3] += np.eye(3)  # the base's block: no motor, decoupled
        return np.linalg.solve(reduced, (normal @ motion).T).T

    def watch_null_space(self, sample: Callable[[], tuple[Vector, Vector, Vector]], t: float) -> None:
        """Every NULL_SPACE_CHECK_EVERY states, until said once: warn of joints running in the null space
        (``sample``: the hand's desired and actual position and dq of the state answered)."""
        self.answers += 1
        if self.null_space_warned or self.answers % NULL_SPACE_CHECK_EVERY:
            return
        hand_desired, hand_actual, dq = sample()
        hand_error = float(np.linalg.norm(np.asarray(hand_desired) - np.asarray(hand_actual)))
        warning = null_space_warning(self.law.null_space_speed(dq), hand_error, t)
        if warning is not None:
            self.null_space_warned = True
            self.log.say([warning], t)  # the recorder keeps it for the summary, as the simulator's
