"""The constrained robot + motor-circuit dynamics (docs/model.md, Robot and motor model; Contacts).

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
constraint row. Each contact's rows of W are n_j^T J_j + scale_j s_j^T P_j J_j (P_j the
tangential projector, s_j the slip velocity), so one product of [P_j J_j; n_j^T J_j; r] with
Y gives every coupling as floats; p = 0 and p = 1 (scalars) have their own short paths, and
for p >= 2 the small p x p system is solved in floats (numpy's per-call overhead dominates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from bracing_core.contacts import ContactSet, ContactTerms, Plane, Surface
from bracing_core.model import RobotModel
from bracing_core.motors import MotorParams
from bracing_core.types import Vector

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
# The views solve works on (see ConstrainedDynamics.stage).
Stage = tuple[Vector, Vector, Vector, Vector, Vector, Vector]


class ContactRow(NamedTuple):
    """One contact's constants and work rows in ``solve`` (unpacked as a tuple on the hot path)."""

    frame: int
    split: Vector  # (4, 6): [I - n n^T, 0; n^T, 0], the 6 x n frame Jacobian -> [tangential J; J_c]
    block: Vector  # its 4 work rows
    n0: float
    n1: float
    n2: float
    offset: float  # c [m]
    friction: float  # mu
    surface: Surface | None  # a curved surface (its normal changes with the point); None: a plane (n0, n1, n2, offset)


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
    """Evaluates the model of docs/model.md for one robot, its motors and its contacts.

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
        km = motors.reflected_constant
        n, p = robot.nv, len(contacts)
        self._nv, self._p, self._voltage = n, p, voltage
        # Own pinocchio model/data whose armature is J_m: computeAllTerms gives Mc = M + J_m.
        self._pin = robot.with_armature(self.added_inertia)
        self._model, self._data = self._pin.model, self._pin.data
        # A persistent view of pinocchio's h + g (fixed-size Eigen storage, never reallocated).
        self._nle: Vector = self._data.nle
        # rates [dq, drive - Dc dq, di] = G [q, dq, i, 1]; the last column of G is the held
        # input ([0, 0, v / L] or [0, tau, 0], set by ``set_input``). The middle block of the
        # rates becomes ddq once solved. Torque mode: the columns of i are zero.
        m = 3 * n
        g = np.zeros((m, m + 1))
        g[:n, n : 2 * n] = np.eye(n)
        g[n : 2 * n, n : 2 * n] = -np.diag(self.total_damping)
        if voltage:
            g[n : 2 * n, 2 * n : m] = np.diag(km)
            g[2 * n :, n : 2 * n] = -np.diag(km / motors.inductance)
            g[2 * n :, 2 * n : m] = -np.diag(motors.resistance / motors.inductance)
        self._linear = g
        self.current_rows = g[2 * n :]  # di = G[2n:] x: all that depends on the held voltage
        self._input_column = g[2 * n :, m] if voltage else g[n : 2 * n, m]
        self._command: Vector = np.zeros(n)
        # effort = K_m i - D_m dq - J_m ddq as one product with a stage row [q, dq, i, 1, dq, ddq, di].
        effort_map = np.zeros((n, 2 * m + 1))
        if voltage:
            effort_map[:, n : 2 * n] = -np.diag(motors.reflected_damping)
            effort_map[:, 2 * n : m] = np.diag(km)
            effort_map[:, m + 1 + n : m + 1 + 2 * n] = -np.diag(self.added_inertia)
        self._effort_map = effort_map
        self._inverse_inductance = 1.0 / motors.inductance
        self._eps2 = float(contacts.slip_epsilon) ** 2
        # Work rows of solve: per contact j [P_j J_j (3 rows); J_c,j], then r = drive - (h + g) - Dc dq;
        # one product with Mc^-1 J_c^T gives every coupling the contact forces need.
        self._work = np.zeros((4 * p + 1, n))
        self._work_rhs = self._work[4 * p]
        self._work_contacts = self._work[: 4 * p]
        self._normal_rows = self._work[3 : 4 * p : 4]  # J_c (p x n)
        self._ys = np.zeros((p, n))  # rows of (Mc^-1 J_c^T)^T
        rows = []
        for j, (frame, contact) in enumerate(zip(contacts.frame_ids, contacts.contacts, strict=True)):
            normal = contacts.normals[j]
            # [I - n n^T, 0; n^T, 0] @ the 6 x n frame Jacobian = [tangential part of J; J_c]
            # (a curved surface's rows are rewritten at each evaluation, from its normal there)
            split = np.zeros((4, 6))
            split[:3, :3] = np.eye(3) - np.outer(normal, normal)
            split[3, :3] = normal
            n0, n1, n2 = normal.tolist()
            surface = contact.surface
            plane = isinstance(surface, Plane)
            rows.append(
                ContactRow(
                    frame,
                    split,
                    self._work[4 * j : 4 * j + 4],
                    n0,
                    n1,
                    n2,
                    surface.offset if isinstance(surface, Plane) else 0.0,
                    contact.friction,
                    None if plane else surface,
                )
            )
        self._contact_rows = tuple(rows)
        # The scalar path of ``solve`` is for one plane; a curved surface takes the general path.
        self._single_plane = p == 1 and rows[0].surface is None
        if self._single_plane:
            self._single = rows[0]
        self._no_contacts = ContactTerms(
            positions=np.zeros((0, 3)),
            jacobians=np.zeros((0, 3, n)),
            normal_jacobian=np.zeros((0, n)),
            tangent_jacobian=np.zeros((0, n)),
            drift=np.zeros(0),
            residual=np.zeros(0),
            slip_velocity=np.zeros((0, 3)),
            slip_direction=np.zeros((0, 3)),
            friction=contacts.friction,
            normals=contacts.normals,
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
        row = np.empty(6 * n + 1)
        row[:n] = q
        row[n : 2 * n] = dq
        row[2 * n : 3 * n] = current if self._voltage else 0.0
        row[3 * n] = 1.0
        self.set_input(np.asarray(command, dtype=float))
        derivative = self.solve(self.stage(row), True)[2]
        assert derivative is not None
        return derivative

    # -- fast interface for the integrator (Simulator.step) -----------------------------
    def stage(self, row: Vector) -> Stage:
        """The views ``solve`` works on in a contiguous ``row`` of at least 6n + 1 values laid
        out [q, dq, i, 1, dq, ddq, di]: (state [q, dq, i, 1], q, dq, rates [dq, ddq, di], ddq,
        state and rates together)."""
        n = self._nv
        m = 3 * n
        return (
            row[: m + 1],
            row[:n],
            row[n : 2 * n],
            row[m + 1 : 2 * m + 1],
            row[m + 1 + n : m + 1 + 2 * n],
            row[: 2 * m + 1],
        )

    def set_input(self, command: Vector) -> None:
        """Hold ``command`` (v or tau, n values) for the following ``solve`` calls."""
        self._command = command
        if self._voltage:
            np.multiply(command, self._inverse_inductance, out=self._input_column)
        else:
            self._input_column[:] = command

    def solve(self, stage: Stage, full: bool) -> tuple[float, float, Derivative | None]:
        """The model at a stage state [q, dq, i, 1] (see ``stage``) under the held input.

        Writes [dq, ddq, di] into the stage's rates (di = 0 in torque mode) and returns
        (friction power sum mu f_n (dir . slip), constraint power f_n . (J_c dq), the full
        Derivative if ``full`` else None).
        """
        state, q, dq, rates, rates_ddq, head = stage
        model, data = self._model, self._data
        pin.computeAllTerms(model, data, q, dq)
        pin.cholesky.decompose(model, data)
        np.dot(self._linear, state, out=rates)  # [dq, drive - Dc dq, di]
        p = self._p
        # One contact in scalars: an engine step of the paper model takes 50.5 us this way against
        # 81.2 us through _solve_contacts (the general path), measured side by side: worth 38% of a step.
        if self._single_plane:
            frame, split, work_split, n0, n1, n2, offset, mu, _ = self._single
            work, work_jc, eps2 = self._work, self._work[3], self._eps2
            np.subtract(rates_ddq, self._nle, out=self._work_rhs)  # r = drive - (h + g) - Dc dq
            jac = pin.getFrameJacobian(model, data, frame, _WORLD)
            np.dot(split, jac, out=work_split)  # [tangential part of J; J_c]
            s0, s1, s2, normal_velocity = work_split.dot(dq).tolist()  # slip velocity s, J_c dq
            slip2 = s0 * s0 + s1 * s1 + s2 * s2
            slip_norm = math.sqrt(slip2 + eps2)
            a0, a1, a2 = pin.getFrameClassicalAcceleration(model, data, frame, _WORLD).linear.tolist()
            gamma = n0 * a0 + n1 * a1 + n2 * a2
            a = self.baumgarte
            if a or full:
                r0, r1, r2 = pin.updateFramePlacement(model, data, frame).translation.tolist()
                residual = n0 * r0 + n1 * r1 + n2 * r2 - offset
                bias = -gamma - 2.0 * a * normal_velocity - a * a * residual
            else:
                bias = -gamma
            y = pin.cholesky.solve(model, data, work_jc)  # Mc^-1 J_c^T
            t0, t1, t2, jc_y, rhs_y = work.dot(y).tolist()
            # W = J_c - mu J_t = J_c + scale s^T J with scale = -mu / sqrt(|s|^2 + eps^2) (-0.0 for mu = 0).
            scale = -mu / slip_norm
            schur = jc_y + scale * (s0 * t0 + s1 * t1 + s2 * t2)  # W Mc^-1 J_c^T
            if schur == 0.0:  # as np.linalg.solve on the (n + p) system: exactly singular
                raise np.linalg.LinAlgError("Singular matrix: the contact constraint has no effect on the motion")
            force = (bias - rhs_y) / schur
            c = force * scale
            ddq = pin.cholesky.solve(
                model, data, np.array((c * s0, c * s1, c * s2, force, 1.0)).dot(work)
            )  # Mc^-1 (r + W^T f_n)
            rates_ddq[:] = ddq
            friction_power = mu * force * slip2 / slip_norm
            constraint_power = force * normal_velocity
            if not full:
                return friction_power, constraint_power, None
            # Fresh arrays (the caller may keep the Derivative while the work rows change), as
            # views of one: numpy builds a flat array from floats far faster than nested ones.
            values = np.array(
                (r0, r1, r2, s0, s1, s2, s0 / slip_norm, s1 / slip_norm, s2 / slip_norm, gamma, residual, force)
            )
            vectors = values.reshape(4, 1, 3)
            positions, slip, direction = vectors[0], vectors[1], vectors[2]
            drift, residuals, normal_force = values[9:10], values[10:11], values[11:12]
            jacobian = jac[:3]
            terms = ContactTerms(  # positional, in field order (cheaper than keywords)
                positions,
                jacobian[None],  # jacobians
                np.array(work_jc, ndmin=2),  # normal_jacobian
                direction.dot(jacobian),  # tangent_jacobian
                drift,
                residuals,
                slip,  # slip_velocity
                direction,  # slip_direction
                self.contacts.friction,
                self.contacts.normals,
            )
        elif p == 0:
            ddq = pin.cholesky.solve(model, data, rates_ddq - self._nle)
            rates_ddq[:] = ddq
            if not full:
                return 0.0, 0.0, None
            terms = self._no_contacts
            normal_force = np.zeros(0)
            friction_power = constraint_power = 0.0
        else:
            friction_power, constraint_power, ddq, found = self._solve_contacts(dq, rates_ddq, full)
            rates_ddq[:] = ddq
            if found is None:
                return friction_power, constraint_power, None
            terms, normal_force = found
        n = self._nv
        if self._voltage:
            current_rate = rates[2 * n :].copy()
            effort = self._effort_map.dot(head)  # K_m i - D_m dq - J_m ddq
        else:
            current_rate = np.zeros(n)
            effort = np.array(self._command, dtype=float)
        derivative = Derivative(ddq, current_rate, normal_force, effort, terms)
        return friction_power, constraint_power, derivative

    def _solve_contacts(
        self, dq: Vector, rates_ddq: Vector, full: bool
    ) -> tuple[float, float, Vector, tuple[ContactTerms, Vector] | None]:
        """``solve`` for p >= 2 contacts (after the pass and the rates): (friction power,
        constraint power, ddq, (terms, f_n) if ``full``). The p x p couplings are Python
        floats: for a few contacts that is cheaper than numpy's per-call overhead."""
        model, data = self._model, self._data
        work, rows, a, eps2 = self._work, self._contact_rows, self.baumgarte, self._eps2
        np.subtract(rates_ddq, self._nle, out=self._work_rhs)  # r = drive - (h + g) - Dc dq
        gammas: list[float] = []
        residuals: list[float] = []
        positions: list[float] = []  # flat, 3 per contact (numpy converts flat lists faster)
        jacobians = []
        normals = self.contacts.normals.copy() if full else self.contacts.normals
        for j, (frame, split, block, n0, n1, n2, offset, _, surface) in enumerate(rows):
            jac = pin.getFrameJacobian(model, data, frame, _WORLD)
            acceleration = pin.getFrameClassicalAcceleration(model, data, frame, _WORLD).linear
            if surface is not None:  # the normal and the curvature at the point: C, n, H_C
                point = pin.updateFramePlacement(model, data, frame).translation
                residual, normal, hessian = surface.evaluate(point)
                split[:3, :3] = np.eye(3) - np.outer(normal, normal)
                split[3, :3] = normal
                np.dot(split, jac, out=block)
                velocity = jac[:3].dot(dq)
                gammas.append(float(normal.dot(acceleration) + velocity.dot(hessian).dot(velocity)))
                residuals.append(residual)
                if full:
                    positions += point.tolist()
                    jacobians.append(jac[:3])
                    normals[j] = normal
                continue
            np.dot(split, jac, out=block)  # [tangential part of J_j; J_c,j]
            a0, a1, a2 = acceleration.tolist()
            gammas.append(n0 * a0 + n1 * a1 + n2 * a2)
            if a or full:
                r0, r1, r2 = pin.updateFramePlacement(model, data, frame).translation.tolist()
                residuals.append(n0 * r0 + n1 * r1 + n2 * r2 - offset)
                positions += (r0, r1, r2)
                jacobians.append(jac[:3])
            else:
                residuals.append(0.0)
        velocities = self._work_contacts.dot(dq).tolist()  # per contact [slip velocity s_j; J_c,j dq]
        ys = self._ys
        for j, jc in enumerate(self._normal_rows):
            ys[j] = pin.cholesky.solve(model, data, jc)  # Mc^-1 J_c,j^T
        slips, norms, scales, biases = [], [], [], []
        for j, row in enumerate(rows):
            s0, s1, s2, normal_velocity = velocities[4 * j : 4 * j + 4]
            slip_norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + eps2)
            slips.append((s0, s1, s2))
            norms.append(slip_norm)
            scales.append(-row.friction / slip_norm)  # W_j = J_c,j + scale_j s_j^T J_j
            biases.append(-gammas[j] - 2.0 * a * normal_velocity - a * a * residuals[j])
        # Row k is constraint k: sum_j (J_c,k Mc^-1 W_j^T) f_j = b_k - J_c,k Mc^-1 r, from the
        # products of J_c,k Mc^-1 with every work row.
        system, rhs = [], []
        for coupling, bias in zip(ys.dot(work.T).tolist(), biases, strict=True):
            system.append(
                [
                    coupling[4 * j + 3]
                    + scale * (s0 * coupling[4 * j] + s1 * coupling[4 * j + 1] + s2 * coupling[4 * j + 2])
                    for j, ((s0, s1, s2), scale) in enumerate(zip(slips, scales, strict=True))
                ]
            )
            rhs.append(bias - coupling[-1])
        forces = _small_solve(system, rhs)
        combination: list[float] = []
        friction_power = constraint_power = 0.0
        for j, (force, scale, (s0, s1, s2)) in enumerate(zip(forces, scales, slips, strict=True)):
            c = force * scale
            combination += (c * s0, c * s1, c * s2, force)
            friction_power += rows[j].friction * force * (s0 * s0 + s1 * s1 + s2 * s2) / norms[j]
            constraint_power += force * velocities[4 * j + 3]
        combination.append(1.0)
        ddq = pin.cholesky.solve(model, data, np.array(combination).dot(work))  # Mc^-1 (r + W^T f_n)
        if not full:
            return friction_power, constraint_power, ddq, None
        # Fresh arrays, as views of one built from a flat list of floats (see solve).
        p = len(rows)
        directions = [x / norm for (s0, s1, s2), norm in zip(slips, norms, strict=True) for x in (s0, s1, s2)]
        values = np.array([*positions, *(x for slip in slips for x in slip), *directions, *gammas, *residuals, *forces])
        vectors = values[: 9 * p].reshape(3, p, 3)
        jacobian = np.array(jacobians)
        terms = ContactTerms(
            vectors[0],  # positions
            jacobian,
            self._normal_rows.copy(),
            np.matmul(vectors[2][:, None, :], jacobian)[:, 0, :],  # J_t rows s_j^T J_j / |s_j|
            values[9 * p : 10 * p],  # drift
            values[10 * p : 11 * p],  # residual
            vectors[1],  # slip velocity
            vectors[2],  # slip direction
            self.contacts.friction,
            normals,
        )
        return friction_power, constraint_power, ddq, (terms, values[11 * p :])


def _small_solve(a: list[list[float]], b: list[float]) -> list[float]:
    """x with a x = b for a small dense system (``a`` and ``b`` are overwritten): Gaussian
    elimination with partial pivoting, as LAPACK does, in floats: np.linalg.solve costs ~5 us
    of call overhead for a 2 x 2 system."""
    p = len(b)
    for k in range(p):
        pivot, largest = k, abs(a[k][k])
        for i in range(k + 1, p):
            if abs(a[i][k]) > largest:
                pivot, largest = i, abs(a[i][k])
        if largest == 0.0:
            raise np.linalg.LinAlgError("Singular matrix: the contact constraints do not determine the forces")
        a[k], a[pivot], b[k], b[pivot] = a[pivot], a[k], b[pivot], b[k]
        top, diagonal = a[k], a[k][k]
        for i in range(k + 1, p):
            row = a[i]
            factor = row[k] / diagonal
            for c in range(k + 1, p):
                row[c] -= factor * top[c]
            b[i] -= factor * b[k]
    x = [0.0] * p
    for k in range(p - 1, -1, -1):
        top = a[k]
        x[k] = (b[k] - sum(top[c] * x[c] for c in range(k + 1, p))) / top[k]
    return x
