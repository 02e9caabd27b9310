"""The constrained robot + motor-circuit dynamics of SPEC section 2.

Unknowns ddq, f_n (and di in voltage mode) from

    Mc ddq - (J_c - mu J_t)^T f_n = drive - (h + g) - Dc dq
    J_c ddq = -gamma - 2 a J_c dq - a^2 C                    (Baumgarte, a = 0: the paper)
    L di = v - R i - K_m dq                                    (voltage mode only)

with drive = K_m i, Mc = M + J_m, Dc = D + D_m in voltage mode and drive = tau,
Mc = M, Dc = D in torque mode. M, h + g, Jacobians and gamma come from pinocchio.

How it is solved: the dynamics keeps its own copy of the pinocchio model whose
``armature`` is J_m (voltage mode; zero in torque mode), so one ``computeAllTerms`` gives
Mc, h + g and the joint Jacobians, and ``pinocchio.cholesky`` factorises Mc. The contact
forces then come from the p x p Schur complement of the (n + p) system:

    Y = Mc^-1 J_c^T,  (Y^T W^T) f_n = b - Y^T r,  Mc ddq = r + W^T f_n

with W = J_c - mu J_t, r = drive - (h + g) - Dc dq and b the right-hand side of the
constraint row. p = 0 and p = 1 (scalars) have their own short paths.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
import pinocchio as pin

from bracing_sim.core.contacts import ContactSet, ContactTerms
from bracing_sim.core.model import RobotModel
from bracing_sim.core.motors import MotorParams
from bracing_sim.core.types import Vector

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
# Module-level aliases: _solve runs 4x per step, so every lookup counts.
_compute_all_terms = pin.computeAllTerms
_cholesky_decompose = pin.cholesky.decompose
_cholesky_solve = pin.cholesky.solve
_frame_jacobian = pin.getFrameJacobian
_frame_classical_acceleration = pin.getFrameClassicalAcceleration
_update_frame_placement = pin.updateFramePlacement
_dot = np.dot
_subtract = np.subtract
_sqrt = math.sqrt
_array = np.array


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


@dataclass
class Derivative:
    """Everything the model says at one (state, input)."""

    acceleration: Vector  # ddq [rad/s^2]
    current_rate: Vector  # di/dt [A/s] (zeros in torque mode)
    normal_force: Vector  # f_n (p,) [N], on the robot along +normal
    effort: Vector  # link-side motor torque tau [N m]
    contacts: ContactTerms
    active: Vector | None = None  # (p,) bool: contacts holding a force; None = all

    @property
    def friction_force(self) -> Vector:
        """f_t = mu f_n (p,) [N], opposing the slip."""
        return self.contacts.friction * self.normal_force


class ConstrainedDynamics:
    """Evaluates SPEC section 2 for one robot, its motors and its contacts.

    ``evaluate`` runs its pinocchio passes on a private copy of the robot's model (with
    the rotor inertia as armature), so it does not change ``robot.data``.
    """

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
        self.added_inertia, self.total_damping = reflected_terms(robot, motors, mode)
        self._km = motors.reflected_constant
        n, p = robot.nv, len(contacts)
        self._nv, self._p, self._voltage = n, p, voltage
        # Own pinocchio model/data whose armature is J_m: computeAllTerms gives Mc = M + J_m.
        self._pin = robot.with_armature(self.added_inertia)
        self._model, self._data = self._pin.model, self._pin.data
        # A persistent view of pinocchio's h + g (fixed-size Eigen storage, never reallocated).
        self._nle: Vector = self._data.nle
        self._reflected_damping = motors.reflected_damping
        # rates [dq, drive - Dc dq, di] = G [q, dq, i, 1]; the last column of G is the held
        # input ([0, 0, v / L] or [0, tau, 0], set by ``_set_input``). The middle block of the
        # rates becomes ddq once solved. Torque mode: the columns of i are zero.
        m = 3 * n
        g = np.zeros((m, m + 1))
        g[:n, n : 2 * n] = np.eye(n)
        g[n : 2 * n, n : 2 * n] = -np.diag(self.total_damping)
        if voltage:
            g[n : 2 * n, 2 * n : m] = np.diag(self._km)
            g[2 * n :, n : 2 * n] = -np.diag(self._km / motors.inductance)
            g[2 * n :, 2 * n : m] = -np.diag(motors.resistance / motors.inductance)
        self._linear = g
        self._input_column = g[2 * n :, m] if voltage else g[n : 2 * n, m]
        self._command: Vector = np.zeros(n)
        self._effort_map = np.hstack(
            (np.zeros((n, n)), -np.diag(self._reflected_damping), np.diag(self._km), np.zeros((n, 1)))
        )
        self._inverse_inductance = 1.0 / motors.inductance
        self._frames = list(contacts.frame_ids)
        self._eps2 = float(contacts.slip_epsilon) ** 2
        if p == 1:
            contact = contacts.contacts[0]
            normal = np.array(contacts._normals[0])
            self._frame0 = self._frames[0]
            self._normal0: Vector = normal
            self._offset0 = float(contact.offset)
            self._mu0 = float(contact.friction)
            # [I - n n^T; n^T] @ J = [tangential part of J; J_c]
            self._split = np.vstack((np.eye(3) - np.outer(normal, normal), normal))
            # Work rows of _solve: [P J (3 rows); J_c; r] with r = drive - (h + g) - Dc dq, and the
            # coefficients [f_n (-mu / |s|) s, f_n, 1] that combine them into r + W^T f_n.
            self._work = np.zeros((5, n))
            self._work_split, self._work_jc, self._work_rhs = self._work[:4], self._work[3], self._work[4]
            self._combination = np.array([0.0, 0.0, 0.0, 0.0, 1.0])  # [0, 0, 0, f_n, 1] without friction
            self._contact_constants = (
                self._work,
                self._work_rhs,
                self._work_split,
                self._work_jc,
                self._split,
                self._frame0,
                tuple(normal.tolist()),
                self._eps2,
                self._mu0,
                self._offset0,
                self._combination,
            )
        self._no_contacts = ContactTerms(
            positions=np.zeros((0, 3)),
            jacobians=np.zeros((0, 3, n)),
            normal_jacobian=np.zeros((0, n)),
            tangent_jacobian=np.zeros((0, n)),
            drift=np.zeros(0),
            residual=np.zeros(0),
            slip_velocity=np.zeros((0, 3)),
            slip_direction=np.zeros((0, 3)),
            friction=contacts._friction,
            normals=contacts._normals,
        )

    @property
    def n(self) -> int:
        return self.robot.nv

    def with_contacts(self, contacts: ContactSet) -> ConstrainedDynamics:
        """The same robot, motors, mode and Baumgarte gain with another set of contacts."""
        return ConstrainedDynamics(self.robot, self.motors, contacts, self.mode, self.baumgarte)

    def evaluate(self, q: Vector, dq: Vector, current: Vector, command: Vector) -> Derivative:
        """ddq, di, f_n at state (q, dq, i) under the held input (v or tau)."""
        n = self._nv
        state = np.empty(3 * n + 1)
        state[:n] = q
        state[n : 2 * n] = dq
        state[2 * n : 3 * n] = current if self._voltage else 0.0
        state[3 * n] = 1.0
        self._set_input(np.asarray(command, dtype=float))
        derivative = self._solve(self._stage(state, np.empty(3 * n)), True)[2]
        assert derivative is not None
        return derivative

    # -- fast interface for the integrator (Simulator.step) -----------------------------
    def _stage(self, state: Vector, rates: Vector) -> tuple[Vector, Vector, Vector, Vector, Vector]:
        """The views ``_solve`` works on: (state, q, dq, rates, ddq part of rates).

        ``state`` = [q, dq, i, 1] (3n + 1) and ``rates`` (3n) must be contiguous.
        """
        n = self._nv
        return state, state[:n], state[n : 2 * n], rates, rates[n : 2 * n]

    def _set_input(self, command: Vector) -> None:
        """Hold ``command`` (v or tau, n values) for the following ``_solve`` calls."""
        self._command = command
        if self._voltage:
            np.multiply(command, self._inverse_inductance, out=self._input_column)
        else:
            self._input_column[:] = command

    def _solve(
        self, stage: tuple[Vector, Vector, Vector, Vector, Vector], full: bool
    ) -> tuple[float, float, Derivative | None]:
        """The model at a stage state [q, dq, i, 1] (see ``_stage``) under the held input.

        Writes [dq, ddq, di] into the stage's rates (di = 0 in torque mode) and returns
        (friction power sum mu f_n (dir . slip), constraint power f_n . (J_c dq), the full
        Derivative if ``full`` else None).
        """
        state, q, dq, rates, rates_ddq = stage
        model, data = self._model, self._data
        _compute_all_terms(model, data, q, dq)
        _cholesky_decompose(model, data)
        _dot(self._linear, state, out=rates)  # [dq, drive - Dc dq, di]
        p = self._p
        friction_power = constraint_power = 0.0
        if p == 1:
            (work, work_rhs, work_split, work_jc, split, frame, normal, eps2, mu, offset, combination) = (
                self._contact_constants
            )
            _subtract(rates_ddq, self._nle, out=work_rhs)  # r = drive - (h + g) - Dc dq
            jac = _frame_jacobian(model, data, frame, _WORLD)[:3]
            _dot(split, jac, out=work_split)  # [tangential part of J; J_c]
            split_velocity = work_split.dot(dq)  # [slip velocity s; J_c dq]
            s0, s1, s2, normal_velocity = split_velocity.tolist()
            slip2 = s0 * s0 + s1 * s1 + s2 * s2
            slip_norm = _sqrt(slip2 + eps2)
            n0, n1, n2 = normal
            a0, a1, a2 = _frame_classical_acceleration(model, data, frame, _WORLD).linear.tolist()
            gamma = n0 * a0 + n1 * a1 + n2 * a2
            a = self.baumgarte
            if a or full:
                position = _update_frame_placement(model, data, frame).translation
                r0, r1, r2 = position.tolist()
                residual = n0 * r0 + n1 * r1 + n2 * r2 - offset
                bias = -gamma - 2.0 * a * normal_velocity - a * a * residual
            else:
                bias = -gamma
            y = _cholesky_solve(model, data, work_jc)  # Mc^-1 J_c^T
            t0, t1, t2, jc_y, rhs_y = work.dot(y).tolist()
            # W = J_c - mu J_t = J_c + scale s^T J with scale = -mu / sqrt(|s|^2 + eps^2).
            scale = -mu / slip_norm
            schur = jc_y + scale * (s0 * t0 + s1 * t1 + s2 * t2) if mu else jc_y  # W Mc^-1 J_c^T
            if schur == 0.0:  # as np.linalg.solve on the (n + p) system: exactly singular
                raise np.linalg.LinAlgError("Singular matrix: the contact constraint has no effect on the motion")
            force = (bias - rhs_y) / schur
            if mu:
                c = force * scale
                combination = _array((c * s0, c * s1, c * s2, force, 1.0))
            else:
                combination[3] = force
            ddq = _cholesky_solve(model, data, combination.dot(work))  # Mc^-1 (r + W^T f_n)
            rates_ddq[:] = ddq
            friction_power = mu * force * slip2 / slip_norm
            constraint_power = force * normal_velocity
            if not full:
                return friction_power, constraint_power, None
            slip = split_velocity[:3]
            direction = slip / slip_norm
            terms = ContactTerms(  # positional, in field order (cheaper than keywords)
                np.array(position, ndmin=2),  # positions
                jac[None],  # jacobians
                np.array(work_jc, ndmin=2),  # normal_jacobian
                direction.dot(jac)[None],  # tangent_jacobian
                np.array([gamma]),  # drift
                np.array([residual]),  # residual
                slip[None],  # slip_velocity
                direction[None],  # slip_direction
                self.contacts._friction,  # friction
                self.contacts._normals,  # normals
            )
            normal_force = np.array([force])
        elif p == 0:
            ddq = _cholesky_solve(model, data, rates_ddq - self._nle)
            rates_ddq[:] = ddq
            if not full:
                return 0.0, 0.0, None
            terms = self._no_contacts
            normal_force = np.zeros(0)
        else:
            rhs = rates_ddq - self._nle
            terms = self.contacts.evaluate_data(model, data, dq)
            jcs = terms.normal_jacobian
            ws = jcs - terms.friction[:, None] * terms.tangent_jacobian
            jc_dq = jcs.dot(dq)
            a = self.baumgarte
            bias = -terms.drift - 2.0 * a * jc_dq - a * a * terms.residual
            ys = np.empty((self._nv, p))
            for j in range(p):
                ys[:, j] = pin.cholesky.solve(model, data, jcs[j])  # Mc^-1 J_c^T
            normal_force = np.linalg.solve(ys.T.dot(ws.T), bias - ys.T.dot(rhs))
            ddq = pin.cholesky.solve(model, data, rhs + ws.T.dot(normal_force))
            rates_ddq[:] = ddq
            slip_rate = (terms.slip_direction * terms.slip_velocity).sum(axis=1)
            friction_power = float(np.sum(terms.friction * normal_force * slip_rate))
            constraint_power = float(normal_force.dot(jc_dq))
            if not full:
                return friction_power, constraint_power, None
        n = self._nv
        if self._voltage:
            current_rate = rates[2 * n :].copy()
            effort = self._effort_map.dot(state)  # K_m i - D_m dq
            effort -= self.added_inertia * ddq
        else:
            current_rate = np.zeros(n)
            effort = np.array(self._command, dtype=float)
        derivative = Derivative(ddq, current_rate, normal_force, effort, terms)
        return friction_power, constraint_power, derivative
