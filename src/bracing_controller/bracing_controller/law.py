"""The decoupled force/position law of SPEC section 2 (paper eqs. 36-41), no ROS.

    B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
    tau = B^+ (a - A f_nd) + (I - B^+ B) l
    l = sum_j J_j^T [Kp_j (r_dj - r_j) + Kd_j (dr_dj - dr_j)] + J_h^T [Kp_h (r_dh - r_h) + Kd_h (dr_dh - dr_h)]
    v = K_V tau                                   (voltage mode; tau itself in torque mode)

Each task uses only the world axes the configuration names. With no contacts, tau = l.

Implementation: the controller keeps its own pinocchio copy of the robot whose armature is
the rotor inertia (voltage mode), so one ``computeAllTerms`` gives Mc, h + g and the joint
Jacobians, and ``pinocchio.cholesky`` gives B^T = Mc^-1 J_c^T. For one contact B is a row:
B^+ = B^T / (B B^T) and its only singular value is |B|, so no SVD is needed; more contacts
use the general matrix code (with the SVD test of ``_pseudo_inverse``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from bracing_controller.config import ControllerConfig
from bracing_controller.trajectory import Circle, Hold, Trajectory
from bracing_sim.config import Plant
from bracing_sim.core.dynamics import InputMode, reflected_terms
from bracing_sim.core.types import Vector

# Smallest singular value of B (relative to its largest) below which B^+ is damped.
SINGULAR_RATIO = 1e-8

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class ControlOutput:
    command: Vector  # v [V] or tau [N m], model joint order
    torque: Vector  # tau of eq. 38 [N m]
    hand_desired: Vector  # (3,) [m]
    hand_actual: Vector
    brace_desired: Vector  # (p, 3) [m]
    brace_actual: Vector
    desired_normal_force: Vector  # (p,) [N]
    damped: bool  # True when B was near-singular and a damped inverse was used


@dataclass
class _Task:
    frame: int
    selector: Vector  # (k, 3) rows of the world axes used
    kp: Vector  # (k,)
    kd: Vector

    def __post_init__(self) -> None:
        # Per world axis (zero on unused axes): S^T diag(k) S is diagonal for unit-axis rows S.
        self.kp_axes: Vector = np.diag(self.selector.T @ np.diag(self.kp) @ self.selector).copy()
        self.kd_axes: Vector = np.diag(self.selector.T @ np.diag(self.kd) @ self.selector).copy()
        self.kp_list = tuple(self.kp_axes.tolist())
        self.kd_list = tuple(self.kd_axes.tolist())


class DecoupledController:
    """One control update per measured state; the same object runs in the node and in tests."""

    def __init__(self, config: ControllerConfig, plant: Plant | None = None) -> None:
        self.config = config
        self.plant = plant if plant is not None else Plant(config.shared)
        robot = self.plant.robot
        self.robot = robot
        self.contact_set = self.plant.contact_set
        self.mode = config.shared.input_mode
        self._added_inertia, self._damping = reflected_terms(robot, self.plant.motors, self.mode)
        self._voltage_gain = self.plant.to_model_order(config.voltage_gain)
        contacts = config.shared.contacts
        self.desired_normal_force = np.array([c.desired_normal_force for c in contacts], dtype=float)
        hand = config.hand
        self._hand = _Task(
            self.plant.frame_id(hand.frame, "hand.frame"),
            np.eye(3)[list(hand.axes)],
            np.array(hand.kp),
            np.array(hand.kd),
        )
        self._braces = [
            _Task(fid, np.eye(3)[list(c.brace_axes)], np.array(c.kp), np.array(c.kd))
            for fid, c in zip(self.contact_set.frame_ids, contacts, strict=True)
        ]
        # Targets that default to the first measured state.
        self._hand_trajectory: Trajectory | None = None
        self._brace_targets: Vector | None = None
        self._identity = np.eye(robot.nv)
        # Own pinocchio copy with the rotor inertia as armature: computeAllTerms gives Mc directly.
        self._pin = robot.with_armature(self._added_inertia)
        self._model, self._data = self._pin.model, self._pin.data
        self._nle: Vector = self._data.nle  # persistent view of h + g (fixed-size Eigen storage)
        if len(self._braces) == 1:
            plane = self.contact_set.contacts[0]
            normal = np.asarray(plane.normal, dtype=float)
            self._friction = float(plane.friction)
            self._eps2 = float(self.contact_set.slip_epsilon) ** 2
            self._normal_tuple = tuple(normal.tolist())
            # [I - n n^T; n^T] @ J = [tangential part of J; J_c]
            self._split = np.vstack((np.eye(3) - np.outer(normal, normal), normal))
            # Work rows of _braced_torque: [P J (3); J_c; h + g + Dc dq; l], one product with B^T gives all.
            self._work = np.zeros((6, robot.nv))
            self._work_split, self._work_jc = self._work[:4], self._work[3]
            self._work_bias, self._work_null = self._work[4], self._work[5]

    def reset(self) -> None:
        """Forget the targets taken from the first state (a new run starts)."""
        self._hand_trajectory = None
        self._brace_targets = None

    def _init_targets(self) -> None:
        """Targets not given in the configuration: the current positions (after ``computeAllTerms``)."""
        model, data = self._model, self._data
        pin.updateFramePlacements(model, data)
        cfg = self.config.hand.trajectory
        if cfg.kind == "circle":
            self._hand_trajectory = Circle(cfg.center, cfg.radius, cfg.period, cfg.direction, cfg.phase, cfg.plane)
        else:
            point = cfg.point if cfg.point is not None else tuple(data.oMf[self._hand.frame].translation)
            self._hand_trajectory = Hold((float(point[0]), float(point[1]), float(point[2])))
        self._brace_targets = np.array(
            [
                c.target if c.target is not None else data.oMf[t.frame].translation.copy()
                for c, t in zip(self.config.shared.contacts, self._braces, strict=True)
            ],
            dtype=float,
        ).reshape(len(self._braces), 3)

    def update(self, t: float, q: Vector, dq: Vector) -> ControlOutput:
        """The command for the measured state (q, dq) at time t [s] (model joint order)."""
        model, data = self._model, self._data
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        pin.computeAllTerms(model, data, q, dq)
        if self._hand_trajectory is None:
            self._init_targets()
        assert self._hand_trajectory is not None and self._brace_targets is not None

        # l: PD tasks along the configured axes (eq. 39), per axis in floats (3-vectors).
        hand_desired, hand_velocity_desired = self._hand_trajectory.sample(t)
        hand = self._hand
        jacobian = pin.getFrameJacobian(model, data, hand.frame, _WORLD)[:3]
        hand_actual = np.array(pin.updateFramePlacement(model, data, hand.frame).translation)
        (p0, p1, p2), (d0, d1, d2) = hand.kp_list, hand.kd_list
        r0, r1, r2 = hand_desired.tolist()
        a0, a1, a2 = hand_actual.tolist()
        v0, v1, v2 = hand_velocity_desired.tolist()
        w0, w1, w2 = jacobian.dot(dq).tolist()
        force = np.array(
            (p0 * (r0 - a0) + d0 * (v0 - w0), p1 * (r1 - a1) + d1 * (v1 - w1), p2 * (r2 - a2) + d2 * (v2 - w2))
        )
        null_input = force.dot(jacobian)  # J^T force
        brace_targets = self._brace_targets
        brace_actual = np.empty((len(self._braces), 3))
        brace_jacobians = []
        for j, task in enumerate(self._braces):
            jacobian = pin.getFrameJacobian(model, data, task.frame, _WORLD)[:3]
            brace_jacobians.append(jacobian)
            actual = brace_actual[j]
            actual[:] = pin.updateFramePlacement(model, data, task.frame).translation
            (p0, p1, p2), (d0, d1, d2) = task.kp_list, task.kd_list
            r0, r1, r2 = brace_targets[j].tolist()
            a0, a1, a2 = actual.tolist()
            w0, w1, w2 = jacobian.dot(dq).tolist()
            # desired brace velocity: 0
            force = np.array(
                (p0 * (r0 - a0) + d0 * (0.0 - w0), p1 * (r1 - a1) + d1 * (0.0 - w1), p2 * (r2 - a2) + d2 * (0.0 - w2))
            )
            null_input += force.dot(jacobian)
        if self.config.gravity_compensation:
            null_input += pin.computeGeneralizedGravity(model, data, q)

        damped = False
        p = len(self._braces)
        if p == 1:
            torque, damped = self._braced_torque(brace_jacobians[0], dq, null_input)
        elif p:
            terms = self.contact_set.evaluate_data(model, data, dq)
            pin.cholesky.decompose(model, data)
            jc = terms.normal_jacobian
            b = np.array([pin.cholesky.solve(model, data, row) for row in jc])  # B = J_c Mc^-1 (Mc symmetric)
            a_matrix = b @ (jc - terms.friction[:, None] * terms.tangent_jacobian).T
            a_vector = b @ (self._nle + self._damping * dq) - terms.drift
            b_pinv, damped = self._pseudo_inverse(b)
            torque = (
                b_pinv @ (a_vector - a_matrix @ self.desired_normal_force) + (self._identity - b_pinv @ b) @ null_input
            )
        else:
            torque = null_input
        command = self._voltage_gain * torque if self.mode is InputMode.VOLTAGE else torque
        return ControlOutput(
            command=command,
            torque=torque,
            hand_desired=hand_desired,
            hand_actual=hand_actual,
            brace_desired=brace_targets.copy(),
            brace_actual=brace_actual,
            desired_normal_force=self.desired_normal_force.copy(),
            damped=damped,
        )

    def _braced_torque(self, jacobian: Vector, dq: Vector, null_input: Vector) -> tuple[Vector, bool]:
        """Eq. 38 for one contact (B is a row), from the pass of ``update``; ``jacobian``: its 3 x n J."""
        model, data = self._model, self._data
        pin.cholesky.decompose(model, data)
        work = self._work  # rows [P J (3); J_c; h + g + Dc dq; l]
        np.dot(self._split, jacobian, out=self._work_split)
        bias = self._work_bias
        np.multiply(self._damping, dq, out=bias)
        bias += self._nle
        self._work_null[:] = null_input
        s0, s1, s2, _ = self._work_split.dot(dq).tolist()  # slip velocity s, J_c dq
        n0, n1, n2 = self._normal_tuple
        a0, a1, a2 = pin.getFrameClassicalAcceleration(model, data, self._braces[0].frame, _WORLD).linear.tolist()
        gamma = n0 * a0 + n1 * a1 + n2 * a2
        y = pin.cholesky.solve(model, data, self._work_jc)  # B^T = Mc^-1 J_c^T
        t0, t1, t2, jc_y, bias_y, null_y = work.dot(y).tolist()
        mu = self._friction
        if mu:  # A = B (J_c - mu J_t)^T, J_t = s^T J / sqrt(|s|^2 + eps^2)
            a_matrix = jc_y - mu / math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + self._eps2) * (s0 * t0 + s1 * t1 + s2 * t2)
        else:
            a_matrix = jc_y
        a_vector = bias_y - gamma  # B (h + g + Dc dq) - gamma
        bb = float(y.dot(y))  # B B^T = |B|^2, the square of B's only singular value
        if bb > 1e-280:  # |B| > 1e-140: the SVD test of _pseudo_inverse passes (its ratio is 1 for one row)
            damped = False
            b_pinv = y / bb
        else:  # B = 0 (or tiny): the general test, and its damped inverse
            pinv, damped = self._pseudo_inverse(y[None, :])
            b_pinv = pinv[:, 0]
        # tau = B^+ (a - A f_nd) + (I - B^+ B) l = l + B^+ ((a - A f_nd) - B l)
        excess = a_vector - a_matrix * float(self.desired_normal_force[0]) - null_y
        torque = null_input + b_pinv * excess
        return torque, damped

    def _pseudo_inverse(self, b: Vector) -> tuple[Vector, bool]:
        """B^+ = B^T (B B^T)^-1, damped (B^T (B B^T + lambda I)^-1) when B is near-singular."""
        gram = b @ b.T
        singular = np.linalg.svd(b, compute_uv=False)
        if singular[-1] > SINGULAR_RATIO * max(singular[0], 1e-300):
            return np.asarray(np.linalg.solve(gram, b).T, dtype=np.float64), False
        lam = self.config.damping_lambda * max(singular[0] ** 2, 1.0)
        return np.asarray(np.linalg.solve(gram + lam * np.eye(gram.shape[0]), b).T, dtype=np.float64), True
