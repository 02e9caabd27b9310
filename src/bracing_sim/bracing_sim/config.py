"""Typed configuration of the plant (robot, motors, contacts) and of the simulator.

``SharedConfig`` is what both nodes read from the ``/**`` section of a scenario file;
``Plant`` is the one robot model built from it, used by the simulator and the
controller alike. Everything is validated here, once, with errors naming the parameter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bracing_sim.core.contacts import ContactSet, PlaneContact
from bracing_sim.core.dynamics import ConstrainedDynamics, Derivative, InputMode
from bracing_sim.core.model import ModelError, RobotModel
from bracing_sim.core.motors import MotorParams
from bracing_sim.core.simulator import DivergenceError, Simulator
from bracing_sim.core.types import Vector
from bracing_sim.params import (
    ConfigError,
    Params,
    check_known,
    get_bool,
    get_float,
    get_floats,
    get_int,
    get_str,
    get_strs,
    resolve_file,
)

AXES = ("x", "y", "z")
MOTOR_FIELDS = ("torque_constant", "resistance", "inductance", "rotor_inertia", "gear_ratio", "gear_damping")

# Parameters read by both nodes (the scenario file's /** section), with defaults.
SHARED_PARAMETERS: dict[str, object] = {
    "robot.urdf": "",
    "robot.joint_names": [],
    "robot.gravity": [0.0, 0.0, -9.81],
    "input_mode": "voltage",
    **{f"motors.{f}": [] for f in MOTOR_FIELDS},
    "motors.voltage_limit": 0.0,
    "motors.torque_limit": 0.0,
    "contacts.names": [],
}
# Fields of each contacts.<name> section.
CONTACT_FIELDS: dict[str, object] = {
    "frame": "",
    "normal": [0.0, 0.0, 1.0],
    "offset": 0.0,
    "friction": 0.0,
    "desired_normal_force": 0.0,
    "brace_axes": [],
    "kp": [],
    "kd": [],
    "target": [],
    "unilateral": False,
}
SIMULATOR_PARAMETERS: dict[str, object] = {
    "initial_position": [],
    "initial_velocity": [],
    "step": 0.001,
    "substeps": 1,
    "duration": 10.0,
    "baumgarte": 0.0,
    "slip_epsilon": 1e-4,
    "contact_tolerance": 1e-6,
    "stepping": "lockstep",
    "real_time_factor": 1.0,
    "command_timeout": 5.0,
    "watchdog_policy": "hold",
    "min_subscribers": 1,
    "wait_for_recorder": False,
    "divergence_residual": 0.01,
    "divergence_speed": 1000.0,
    "log_throttle_period": 1.0,
}


def axes_indices(name: str, axes: Sequence[str]) -> tuple[int, ...]:
    for axis in axes:
        if axis not in AXES:
            raise ConfigError(f"{name}: axes must be among x, y, z, got {list(axes)}")
    if len(set(axes)) != len(axes):
        raise ConfigError(f"{name}: duplicate axes in {list(axes)}")
    return tuple(AXES.index(a) for a in axes)


@dataclass(frozen=True)
class ContactConfig:
    """contacts.<name>: the plane, and the controller's force and brace task for it."""

    name: str
    frame: str
    normal: tuple[float, float, float]
    offset: float  # c [m]
    friction: float  # mu
    desired_normal_force: float  # f_nd [N]
    brace_axes: tuple[int, ...]  # world axis indices of the brace task
    kp: tuple[float, ...]  # one per brace axis
    kd: tuple[float, ...]
    target: tuple[float, float, float] | None  # None: the brace point's initial position
    unilateral: bool = False  # the plane only pushes: release and touchdown (bilateral: the paper)

    @classmethod
    def from_params(cls, params: Params, name: str) -> ContactConfig:
        key = f"contacts.{name}."
        frame = get_str(params, key + "frame", None)
        normal = get_floats(params, key + "normal", [0.0, 0.0, 1.0], length=3)
        if float(np.linalg.norm(normal)) < 1e-9:
            raise ConfigError(f"{key}normal: must be a non-zero vector, got {list(normal)}")
        axes_names = get_strs(params, key + "brace_axes", [])
        axes = axes_indices(key + "brace_axes", axes_names)
        hint = f"one per brace axis {list(axes_names)}"
        kp = get_floats(params, key + "kp", [], length=len(axes), length_hint=hint)
        kd = get_floats(params, key + "kd", [], length=len(axes), length_hint=hint)
        target = get_floats(params, key + "target", [])
        if target and len(target) != 3:
            raise ConfigError(f"{key}target: expected [x, y, z] or an empty list, got {list(target)}")
        return cls(
            name=name,
            frame=frame,
            normal=(normal[0], normal[1], normal[2]),
            offset=get_float(params, key + "offset", 0.0),
            friction=get_float(params, key + "friction", 0.0, minimum=0.0),
            desired_normal_force=get_float(params, key + "desired_normal_force", 0.0),
            brace_axes=axes,
            kp=kp,
            kd=kd,
            target=(target[0], target[1], target[2]) if target else None,
            unilateral=get_bool(params, key + "unilateral", False),
        )

    def plane(self) -> PlaneContact:
        return PlaneContact(self.name, self.frame, np.array(self.normal), self.offset, self.friction, self.unilateral)


@dataclass(frozen=True)
class SharedConfig:
    """robot, motors, contacts, input mode: the plant both nodes agree on."""

    urdf: Path
    joint_names: tuple[str, ...]  # the configuration's joint order (motors are listed in it)
    gravity: tuple[float, float, float]
    input_mode: InputMode
    motors: MotorParams  # in joint_names order
    contacts: tuple[ContactConfig, ...]

    @classmethod
    def from_params(cls, params: Params, search_dirs: Sequence[Path] = ()) -> SharedConfig:
        urdf = resolve_file(get_str(params, "robot.urdf", None), "robot.urdf", search_dirs)
        joint_names = get_strs(params, "robot.joint_names", [])
        if not joint_names:
            raise ConfigError("robot.joint_names: expected the list of actuated joints, got none")
        n = len(joint_names)
        gravity = get_floats(params, "robot.gravity", [0.0, 0.0, -9.81], length=3)
        try:
            mode = InputMode.parse(get_str(params, "input_mode", "voltage"))
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        hint = f"one per joint of robot.joint_names ({n})"
        arrays = {
            f: np.array(get_floats(params, f"motors.{f}", None, length=n, length_hint=hint)) for f in MOTOR_FIELDS
        }
        try:
            motors = MotorParams(
                **arrays,
                voltage_limit=get_float(params, "motors.voltage_limit", 0.0, minimum=0.0),
                torque_limit=get_float(params, "motors.torque_limit", 0.0, minimum=0.0),
            )
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        names = get_strs(params, "contacts.names", [])
        contacts = tuple(ContactConfig.from_params(params, name) for name in names)
        return cls(urdf, joint_names, (gravity[0], gravity[1], gravity[2]), mode, motors, contacts)


class Plant:
    """The robot model, motors (model joint order) and contacts built from a SharedConfig.

    One implementation for simulator and controller: both build their plant here.
    """

    def __init__(self, config: SharedConfig, slip_epsilon: float = 1e-4) -> None:
        try:
            self.robot = RobotModel.from_urdf(config.urdf, config.gravity)
            # Index array taking configuration-ordered data to model order.
            self.order = self.robot.joint_permutation(config.joint_names)
        except ModelError as exc:
            raise ConfigError(str(exc)) from None
        for contact in config.contacts:
            self.frame_id(contact.frame, f"contacts.{contact.name}.frame")
        self.contact_set = ContactSet(self.robot, [c.plane() for c in config.contacts], slip_epsilon)
        self.config = config
        self.joint_names = self.robot.joint_names  # model order: the order of every message
        self.motors = config.motors.permuted(self.order)
        self.mode = config.input_mode

    def frame_id(self, name: str, parameter: str) -> int:
        """The model frame ``name``; a ConfigError naming ``parameter`` if there is none."""
        try:
            return self.robot.frame_id(name)
        except ModelError as exc:
            raise ConfigError(f"{parameter}: {exc}") from None

    def to_model_order(self, values: Sequence[float]) -> np.ndarray:
        return np.asarray(values, dtype=float)[self.order]

    def dynamics(self, baumgarte: float = 0.0) -> ConstrainedDynamics:
        return ConstrainedDynamics(self.robot, self.motors, self.contact_set, self.mode, baumgarte)


@dataclass(frozen=True)
class SimulatorConfig:
    shared: SharedConfig
    initial_position: tuple[float, ...]  # [rad], robot.joint_names order
    initial_velocity: tuple[float, ...]  # [rad/s]
    step: float  # [s]
    substeps: int
    duration: float  # [s] of sim time, 0 = unbounded
    baumgarte: float  # [1/s]
    slip_epsilon: float  # [m/s]
    contact_tolerance: float  # [m]
    stepping: str  # lockstep | real_time
    real_time_factor: float
    command_timeout: float  # [s] wall time
    watchdog_policy: str  # hold | zero
    min_subscribers: int
    divergence_residual: float  # [m]; a larger |C| stops the simulation
    divergence_speed: float = 1000.0  # [rad/s or m/s]; a step leaving a joint faster is not taken
    wait_for_recorder: bool = False  # publish the first state only once every topic has a subscriber
    log_throttle_period: float = 1.0  # [s] wall; at most one report per kind of bad input per period

    @classmethod
    def from_params(cls, params: Params, search_dirs: Sequence[Path] = ()) -> SimulatorConfig:
        check_known(params, [*SHARED_PARAMETERS, *SIMULATOR_PARAMETERS], {"contacts.": CONTACT_FIELDS})
        shared = SharedConfig.from_params(params, search_dirs)
        n = len(shared.joint_names)
        hint = f"one per joint of robot.joint_names ({n})"
        q0 = get_floats(params, "initial_position", None, length=n, length_hint=hint)
        dq0 = get_floats(params, "initial_velocity", [0.0] * n, length=n, length_hint=hint) or (0.0,) * n
        return cls(
            shared=shared,
            initial_position=q0,
            initial_velocity=dq0,
            step=get_float(params, "step", 0.001, positive=True),
            substeps=get_int(params, "substeps", 1, minimum=1),
            duration=get_float(params, "duration", 10.0, minimum=0.0),
            baumgarte=get_float(params, "baumgarte", 0.0, minimum=0.0),
            slip_epsilon=get_float(params, "slip_epsilon", 1e-4, positive=True),
            contact_tolerance=get_float(params, "contact_tolerance", 1e-6, positive=True),
            stepping=get_str(params, "stepping", "lockstep", choices=("lockstep", "real_time")),
            real_time_factor=get_float(params, "real_time_factor", 1.0, positive=True),
            command_timeout=get_float(params, "command_timeout", 5.0, positive=True),
            watchdog_policy=get_str(params, "watchdog_policy", "hold", choices=("hold", "zero")),
            min_subscribers=get_int(params, "min_subscribers", 1, minimum=0),
            divergence_residual=get_float(params, "divergence_residual", 0.01, positive=True),
            divergence_speed=get_float(params, "divergence_speed", 1000.0, positive=True),
            wait_for_recorder=get_bool(params, "wait_for_recorder", False),
            log_throttle_period=get_float(params, "log_throttle_period", 1.0, minimum=0.0),
        )


def _finite(a: np.ndarray) -> bool:
    # A finite a . a means every entry is finite (0.7 us); else check exactly (a . a may overflow).
    return math.isfinite(np.vdot(a, a)) or bool(np.isfinite(a).all())


def check_step(config: SimulatorConfig, d: Derivative, velocity: Vector, *also_finite: Vector) -> float:
    """The largest |C| of a held contact after a step (``d``: the step's answer, ``velocity``: the
    new dq), or DivergenceError saying why the step must not stand: non-finite forces (or any of
    ``also_finite``), a joint faster than divergence_speed, a held contact further than
    divergence_residual off its surface. The simulator node refuses such a step; an in-process
    run stops there."""
    forces = (d.normal_force, d.friction_force, d.contacts.slip_velocity)
    if not all(_finite(a) for a in (*forces, *also_finite)):
        raise DivergenceError("non-finite forces or effort")
    speed = float(np.max(np.abs(velocity)))
    if speed > config.divergence_speed:
        # Finite, but a state no arm reaches: from here RK4 overflows a few steps later under any
        # input (a single 1e150 V step does that).
        raise DivergenceError(f"joint speed exceeds divergence_speed {config.divergence_speed}: {speed:.3g}")
    held = d.contacts.residual if d.active is None else d.contacts.residual[d.active]
    residual = float(np.max(np.abs(held))) if held.size else 0.0
    if residual > config.divergence_residual:
        raise DivergenceError(
            f"constraint residual {residual:.3g} m exceeds divergence_residual {config.divergence_residual} m"
        )
    return residual


def build_simulator(config: SimulatorConfig) -> tuple[Plant, Simulator]:
    """The plant and a simulator at the configured start; refuses an infeasible start."""
    plant = Plant(config.shared, config.slip_epsilon)
    q0 = plant.to_model_order(config.initial_position)
    dq0 = plant.to_model_order(config.initial_velocity)
    simulator = Simulator(plant.dynamics(config.baumgarte), config.step, q0, dq0, config.substeps)
    check_start(plant, simulator, config.contact_tolerance)
    return plant, simulator


def check_start(plant: Plant, simulator: Simulator, tolerance: float) -> None:
    """A start state must satisfy every contact (|C| <= tolerance), and every contact must be
    able to push: a frame that no joint can move along the plane's normal (n^T J = 0) gives a
    singular system."""
    if not len(plant.contact_set):
        return
    plant.robot.compute(simulator.position, simulator.velocity)
    terms = plant.contact_set.evaluate(simulator.velocity)
    for contact, row in zip(plant.config.contacts, terms.normal_jacobian, strict=True):
        if float(np.linalg.norm(row)) < 1e-9:
            raise ConfigError(
                f"contacts.{contact.name}: no joint moves frame {contact.frame!r} along the normal "
                f"{list(contact.normal)} at the start (n^T J = 0), so the contact cannot hold a force; "
                f"check contacts.{contact.name}.normal"
            )
    above = np.array([c.unilateral for c in plant.config.contacts]) & (terms.residual > tolerance)
    if above.any():  # a unilateral contact above its plane starts released, in flight
        simulator.set_active(~above)
    for contact, residual, released in zip(plant.config.contacts, terms.residual, above, strict=True):
        if abs(residual) > tolerance and not released:
            raise ConfigError(
                f"infeasible start: contact {contact.name!r} (frame {contact.frame!r}) is {residual:+.6g} m "
                f"off its plane (tolerance {tolerance:g} m); change initial_position or the plane offset"
            )
