"""The constrained robot + motor-circuit dynamics (docs/model.md, Robot and motor model; Contacts).

Unknowns ddq, f_n (and di in voltage mode) from

    Mc ddq - (J_c - mu J_t)^T f_n = drive - (h + g) - Dc dq
    J_c ddq = -gamma - 2 a J_c dq - a^2 C                    (Baumgarte, a = 0: the paper)
    L di = v - R i - K_m dq                                    (voltage mode only)

with drive = K_m i, Mc = M + J_m, Dc = D + D_m in voltage mode and drive = tau,
Mc = M, Dc = D in torque mode. M, h + g, Jacobians and gamma come from pinocchio.

The model is evaluated by the compiled engine (``bracing_engine``, C++ on pinocchio's C++
API: its own model from the same URDF with J_m as armature, the contact forces from the
p x p Schur complement of the (n + p) system). This module describes a robot, its motors
and its contacts to the engine; its answers are the engine's ``Answer`` (named arrays).
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum

import numpy as np

import bracing_engine as engine
from bracing_core.contacts import Contact, ContactSet, Cylinder, Plane, Sphere, Surface
from bracing_core.model import RobotModel
from bracing_core.motors import MotorParams
from bracing_core.types import EngineField, Vector


class InputMode(str, Enum):  # noqa: UP042 (str() / format() of a StrEnum differ; kept as it was)
    VOLTAGE = "voltage"  # motor terminal voltages [V] (eq. 41): motors in the loop
    TORQUE = "torque"  # link-side torques [N m] (eq. 38): direct drive

    @classmethod
    def parse(cls, value: str) -> InputMode:
        try:
            return cls(value)
        except ValueError:
            raise ValueError(f"input_mode: expected 'voltage' or 'torque', got {value!r}") from None


def reflected_terms(robot: RobotModel, motors: MotorParams, mode: InputMode) -> tuple[Vector, Vector]:
    """(Mc - M, Dc): the diagonal inertia and the viscous damping of the joints under ``mode``.

    With the motors in the loop (voltage) the reflected rotor inertia J_m and gear damping
    D_m join the link damping D; with direct drive (torque) only D remains.
    """
    if mode is InputMode.VOLTAGE:
        return motors.reflected_inertia, robot.damping + motors.reflected_damping
    return np.zeros(robot.nv), robot.damping.copy()


def engine_robot(robot: RobotModel) -> engine.Robot:
    """What the engine rebuilds ``robot``'s pinocchio model from."""
    wheels = robot.wheels
    return engine.Robot(
        urdf_path=str(robot.urdf_path),
        gravity=robot.gravity,
        locked_joints=list(robot.locked_joints),
        locked_positions=list(robot.locked_positions),
        mass_scale=robot.mass_scale,
        urdf_xml=robot.urdf_xml,
        left_wheel=wheels.left[0] if wheels else "",
        right_wheel=wheels.right[0] if wheels else "",
        wheel_radius=wheels.radius if wheels else 0.0,
        collision_description=robot.collision_description,
    )


def thermal_applies(motors: MotorParams, mode: InputMode) -> bool:
    """The windings' temperatures are modelled: motors.thermal, and a motor circuit to heat them
    (voltage input; torque input drives the joints directly)."""
    return motors.thermal and mode is InputMode.VOLTAGE


def engine_drive(robot: RobotModel, motors: MotorParams, mode: InputMode) -> engine.Drive:
    """The joints' drive as the engine takes it: motors in the loop (voltage) or direct drive (torque)."""
    voltage = mode is InputMode.VOLTAGE
    added_inertia, damping = reflected_terms(robot, motors, mode)
    return engine.Drive(
        voltage=voltage,
        added_inertia=added_inertia,
        damping=damping,
        torque_constant=motors.reflected_constant,
        resistance=motors.resistance,
        inductance=motors.inductance,
        reflected_damping=motors.reflected_damping if voltage else np.zeros(robot.nv),
        thermal=thermal_applies(motors, mode),
        thermal_resistance=motors.thermal_resistance,
        heat_capacity=motors.heat_capacity,
        ambient=motors.ambient_temperature,
        temperature_coefficient=motors.temperature_coefficient,
    )


def engine_surface(surface: Surface) -> engine.Surface:
    """A surface as the engine takes it."""
    if isinstance(surface, Plane):
        return engine.Surface.plane(surface.normal, surface.offset)
    if isinstance(surface, Sphere):
        return engine.Surface.sphere(surface.center, surface.radius, surface.inside)
    if isinstance(surface, Cylinder):
        return engine.Surface.cylinder(surface.point, surface.axis, surface.radius, surface.inside)
    raise TypeError(f"unknown surface {surface!r}")  # pragma: no cover - Surface is a closed union


def engine_contact(contact: Contact) -> engine.Contact:
    """A contact as the engine takes it."""
    return engine.Contact(
        name=contact.name,
        frame=contact.frame,
        surface=engine_surface(contact.surface),
        friction=contact.friction,
        unilateral=contact.unilateral,
        enforced=contact.enforced,
        coulomb=contact.friction_model == "coulomb",
        geometry=contact.point == "geometry",
    )


class ConstrainedDynamics:
    """The model of docs/model.md for one robot, its motors and its contacts (evaluated by the engine)."""

    def __init__(
        self,
        robot: RobotModel,
        motors: MotorParams,
        contacts: ContactSet,
        mode: InputMode = InputMode.VOLTAGE,
        baumgarte: float = 0.0,
    ) -> None:
        if motors.n != robot.nv:
            raise ValueError(f"motors: {motors.n} motors for {robot.nv} joints")
        if not (np.isfinite(baumgarte) and baumgarte >= 0.0):
            raise ValueError(f"baumgarte: must be >= 0, got {baumgarte}")
        self.robot = robot
        self.motors = motors
        self.contacts = contacts
        self.mode = mode
        self.added_inertia, self.total_damping = reflected_terms(robot, motors, mode)
        self.engine = engine.Dynamics(
            engine_robot(robot),
            engine_drive(robot, motors, mode),
            [engine_contact(c) for c in contacts.contacts],
            float(contacts.slip_epsilon),
            float(baumgarte),
        )
        self._all = [True] * len(contacts)

    @property
    def n(self) -> int:
        return self.robot.nv

    @property
    def thermal(self) -> bool:
        """The windings' temperatures are modelled (``thermal_applies``)."""
        return thermal_applies(self.motors, self.mode)

    baumgarte = EngineField(float)  # a [1/s]: J_c ddq = -gamma - 2 a J_c dq - a^2 C (0: the paper)

    def with_contacts(self, contacts: ContactSet) -> ConstrainedDynamics:
        """The same robot, motors, mode and Baumgarte gain with another set of contacts."""
        return ConstrainedDynamics(self.robot, self.motors, contacts, self.mode, self.baumgarte)

    def evaluate(
        self, q: Vector, dq: Vector, current: Vector, command: Vector, temperature: Vector | None = None
    ) -> engine.Answer:
        """ddq, di, f_n at state (q, dq, i, T) under the held input (v or tau), every contact held
        (``temperature``: the windings' T [degC], R(T) in the circuit; None: ambient)."""
        n = self.n
        current = np.asarray(current, dtype=float) if self.mode is InputMode.VOLTAGE else np.zeros(n)
        if temperature is None:
            temperature = np.full(n, self.motors.ambient_temperature)
        try:
            return self.engine.evaluate(
                np.asarray(q, dtype=float),
                np.asarray(dq, dtype=float),
                current,
                np.asarray(temperature, dtype=float),
                np.asarray(command, dtype=float),
                self._all,
            )
        except engine.SingularError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None

    def terms(self, q: Vector, dq: Vector) -> engine.Answer:
        """Every contact's terms at (q, dq) (positions, Jacobians, residuals, slip), as an answer with no force."""
        return self.engine.terms(np.asarray(q, dtype=float), np.asarray(dq, dtype=float))

    def project(self, q: Vector, rows: Sequence[int], tolerance: float = 1e-13) -> Vector:
        """The posture near ``q`` where the contacts at ``rows`` hold (C = 0), by Newton steps in the
        metric of Mc: q <- q - Mc^-1 J_c^T (J_c Mc^-1 J_c^T)^+ C (the Mc-nearest posture for a flat
        constraint, to first order otherwise). ValueError if 50 steps do not converge."""
        return np.asarray(self.engine.project(np.asarray(q, dtype=float), list(rows), tolerance))
