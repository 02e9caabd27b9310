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
from typing import Any

import numpy as np

from bracing_core import schema
from bracing_core.contacts import ContactSet, PlaneContact
from bracing_core.dynamics import ConstrainedDynamics, Derivative, InputMode
from bracing_core.model import ModelError, RobotModel
from bracing_core.motors import MotorParams
from bracing_core.params import ConfigError, Params, resolve_file
from bracing_core.schema import Values
from bracing_core.simulator import DivergenceError, Simulator
from bracing_core.types import Vector

AXES = ("x", "y", "z")
MOTOR_FIELDS = ("torque_constant", "resistance", "inductance", "rotor_inertia", "gear_ratio", "gear_damping")


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
    def from_values(cls, name: str, values: dict[str, Any]) -> ContactConfig:
        """From the schema's values of contacts.<name> (``schema.read``); controller-only fields may be absent."""
        key = f"contacts.{name}."
        # The simulator does not read the controller's fields: they take the schema's defaults.
        values = {**{p.name: p.default for p in schema.CONTACT if p.default is not schema.REQUIRED}, **values}
        normal = values["normal"]
        if float(np.linalg.norm(normal)) < 1e-9:
            raise ConfigError(f"{key}normal: must be a non-zero vector, got {list(normal)}")
        target = values["target"]
        return cls(
            name=name,
            frame=values["frame"],
            normal=(normal[0], normal[1], normal[2]),
            offset=values["offset"],
            friction=values["friction"],
            desired_normal_force=values["desired_normal_force"],
            brace_axes=axes_indices(key + "brace_axes", values["brace_axes"]),
            kp=tuple(values["kp"]),
            kd=tuple(values["kd"]),
            target=(target[0], target[1], target[2]) if target else None,
            unilateral=values["unilateral"],
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
    def from_values(cls, values: Values, search_dirs: Sequence[Path] = ()) -> SharedConfig:
        urdf = resolve_file(values["robot.urdf"], "robot.urdf", search_dirs)
        gravity = values["robot.gravity"]
        try:
            motors = MotorParams(
                **{f: np.array(values[f"motors.{f}"]) for f in MOTOR_FIELDS},
                voltage_limit=values["motors.voltage_limit"],
                torque_limit=values["motors.torque_limit"],
            )
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        contacts = tuple(ContactConfig.from_values(name, own) for name, own in values.contacts.items())
        return cls(
            urdf,
            values["robot.joint_names"],
            (gravity[0], gravity[1], gravity[2]),
            InputMode(values["input_mode"]),
            motors,
            contacts,
        )


class Plant:
    """The robot model, motors (model joint order) and contacts built from a SharedConfig.

    One implementation for simulator and controller: both build their plant here.
    """

    def __init__(self, config: SharedConfig, slip_epsilon: float) -> None:
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
    """The simulator node's configuration: the shared plant, then one field per parameter of
    ``schema.SIMULATOR`` (units and meaning there)."""

    shared: SharedConfig
    initial_position: tuple[float, ...]
    initial_velocity: tuple[float, ...]
    step: float
    substeps: int
    duration: float
    baumgarte: float
    slip_epsilon: float
    contact_tolerance: float
    stepping: str
    real_time_factor: float
    command_timeout: float
    watchdog_policy: str
    min_subscribers: int
    divergence_residual: float
    divergence_speed: float
    wait_for_recorder: bool
    log_throttle_period: float

    @classmethod
    def from_params(cls, params: Params, search_dirs: Sequence[Path] = ()) -> SimulatorConfig:
        """Validated against ``schema.SIMULATOR`` (and the shared parameters)."""
        return cls.from_values(schema.read("simulator", params), search_dirs)

    @classmethod
    def from_values(cls, values: Values, search_dirs: Sequence[Path] = ()) -> SimulatorConfig:
        own = {p.name: values[p.name] for p in schema.SIMULATOR}
        return cls(shared=SharedConfig.from_values(values, search_dirs), **own)


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
