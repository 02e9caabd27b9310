"""The constrained robot + motor-circuit dynamics of SPEC section 2.

Unknowns ddq, f_n (and di in voltage mode) from

    Mc ddq - (J_c - mu J_t)^T f_n = drive - (h + g) - Dc dq
    J_c ddq = -gamma - 2 a J_c dq - a^2 C                    (Baumgarte, a = 0: the paper)
    L di = v - R i - K_m dq                                    (voltage mode only)

with drive = K_m i, Mc = M + J_m, Dc = D + D_m in voltage mode and drive = tau,
Mc = M, Dc = D in torque mode. M, h + g, Jacobians and gamma come from pinocchio.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from bracing_sim.core.contacts import ContactSet, ContactTerms
from bracing_sim.core.model import RobotModel
from bracing_sim.core.motors import MotorParams
from bracing_sim.core.types import Vector


class InputMode(str, Enum):
    VOLTAGE = "voltage"  # motor terminal voltages [V] (eq. 41): motors in the loop
    TORQUE = "torque"  # link-side torques [N m] (eq. 38): direct drive

    @classmethod
    def parse(cls, value: str) -> InputMode:
        try:
            return cls(value)
        except ValueError:
            raise ValueError(f"input_mode: expected 'voltage' or 'torque', got {value!r}") from None


@dataclass
class Derivative:
    """Everything the model says at one (state, input)."""

    acceleration: Vector  # ddq [rad/s^2]
    current_rate: Vector  # di/dt [A/s] (zeros in torque mode)
    normal_force: Vector  # f_n (p,) [N], on the robot along +normal
    effort: Vector  # link-side motor torque tau [N m]
    contacts: ContactTerms

    @property
    def friction_force(self) -> Vector:
        """f_t = mu f_n (p,) [N], opposing the slip."""
        return self.contacts.friction * self.normal_force


class ConstrainedDynamics:
    """Evaluates SPEC section 2 for one robot, its motors and its contacts."""

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
        self.baumgarte = float(baumgarte)
        voltage = mode is InputMode.VOLTAGE
        # Reflected rotor inertia and gear damping only exist with the motors in the loop.
        self.added_inertia: Vector = motors.reflected_inertia if voltage else np.zeros(robot.nv)
        self.total_damping: Vector = robot.damping + (motors.reflected_damping if voltage else 0.0)
        self._km = motors.reflected_constant
        n, p = robot.nv, len(contacts)
        self._kkt = np.zeros((n + p, n + p))
        self._rhs = np.zeros(n + p)
        self._diag = np.diag_indices(n)

    @property
    def n(self) -> int:
        return self.robot.nv

    def evaluate(self, q: Vector, dq: Vector, current: Vector, command: Vector) -> Derivative:
        """ddq, di, f_n at state (q, dq, i) under the held input (v or tau)."""
        robot, n = self.robot, self.robot.nv
        robot.compute(q, dq)
        terms = self.contacts.evaluate(dq)
        voltage = self.mode is InputMode.VOLTAGE
        drive = self._km * current if voltage else command
        kkt, rhs = self._kkt, self._rhs
        kkt[:n, :n] = robot.mass_matrix()
        kkt[self._diag] += self.added_inertia
        rhs[:n] = drive - robot.nonlinear_effects() - self.total_damping * dq
        p = terms.count
        if p:
            jc = terms.normal_jacobian
            kkt[:n, n:] = -(jc - terms.friction[:, None] * terms.tangent_jacobian).T
            kkt[n:, :n] = jc
            a = self.baumgarte
            rhs[n:] = -terms.drift - 2.0 * a * (jc @ dq) - a * a * terms.residual
        solution = np.linalg.solve(kkt, rhs)
        ddq, normal_force = solution[:n], solution[n:]
        if voltage:
            motors = self.motors
            di = (command - motors.resistance * current - self._km * dq) / motors.inductance
            effort = drive - self.added_inertia * ddq - motors.reflected_damping * dq
        else:
            di = np.zeros(n)
            effort = np.array(command, dtype=float)
        return Derivative(ddq, di, normal_force, effort, terms)
