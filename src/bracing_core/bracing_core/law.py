"""The decoupled force/position law (docs/model.md, Control law; paper eqs. 36-41), no ROS.

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
import operator
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from bracing_core import schema
from bracing_core.config import Plant
from bracing_core.controller_config import ControllerConfig
from bracing_core.dynamics import InputMode, reflected_terms
from bracing_core.params import ConfigError
from bracing_core.trajectory import Hold, Trajectory
from bracing_core.types import Vector

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
        self.set_gains(self.kp, self.kd)

    def set_gains(self, kp: Vector, kd: Vector) -> None:
        self.kp, self.kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
        # Per world axis (zero on unused axes): S^T diag(k) S is diagonal for unit-axis rows S.
        self.kp_axes: Vector = np.diag(self.selector.T @ np.diag(self.kp) @ self.selector).copy()
        self.kd_axes: Vector = np.diag(self.selector.T @ np.diag(self.kd) @ self.selector).copy()
        self.kp_list = tuple(self.kp_axes.tolist())
        self.kd_list = tuple(self.kd_axes.tolist())


class DecoupledController:
    """One control update per measured state; the same object runs in the node and in tests."""

    def __init__(
        self, config: ControllerConfig, plant: Plant | None = None, single_contact_fast_path: bool = True
    ) -> None:
        self.config = config
        # The controller does not read the simulator's section: its contact model uses the
        # simulator's default slip regularisation.
        self.plant = plant if plant is not None else Plant(config.shared, schema.default("simulator", "slip_epsilon"))
        robot = self.plant.robot
        self.robot = robot
        self.contact_set = self.plant.braced_set  # obstacles are the simulator's business
        self.mode = config.shared.input_mode
        self._added_inertia, self._damping = reflected_terms(robot, self.plant.motors, self.mode)
        self._voltage_gain = self.plant.to_model_order(config.voltage_gain)
        contacts = config.shared.braced_contacts
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
        # Paths that start from the first measured state.
        self._hand_trajectory: Trajectory | None = None
        self._brace_trajectories: list[Trajectory] = []
        self._brace_targets: Vector | None = None
        self._identity = np.eye(robot.nv)
        # Own pinocchio copy with the rotor inertia as armature: computeAllTerms gives Mc directly.
        self._pin = robot.with_armature(self._added_inertia)
        self._model, self._data = self._pin.model, self._pin.data
        self._nle: Vector = self._data.nle  # persistent view of h + g (fixed-size Eigen storage)
        self._voltage = self.mode is InputMode.VOLTAGE
        # Tasks (hand, then each brace) and their stacked 3 x n translational Jacobians, followed by
        # a row for h + g + Dc dq: one product with B^T = Mc^-1 J_c^T gives all of _braced_torque's.
        self._tasks = (self._hand, *self._braces)
        self._work = np.zeros((3 * len(self._tasks) + 1, robot.nv))
        self._task_jacobians = self._work[:-1]
        self._task_rows = tuple((task, self._work[3 * k : 3 * k + 3]) for k, task in enumerate(self._tasks))
        self._work_bias = self._work[-1]
        self._zero_velocities = [[0.0, 0.0, 0.0]] * len(self._braces)
        self._brace_target_lists: list[list[float]] = []
        self._braces_held = True
        # see _braced_torque: one contact, on a plane
        self._consistent = config.null_space == "dynamically_consistent"
        self._single_contact = (
            single_contact_fast_path and len(self._braces) == 1 and self.contact_set.planar[0] and not self._consistent
        )
        if self._single_contact:
            plane = self.contact_set.contacts[0]
            self._normal = np.asarray(self.contact_set.normals[0], dtype=float)
            self._normal_tuple = tuple(self._normal.tolist())
            self._friction = float(plane.friction)
            self._eps2 = float(self.contact_set.slip_epsilon) ** 2
            self._brace_jacobian = self._work[3:6]
            self._work_jc = np.zeros(robot.nv)

    def retune(self, config: ControllerConfig) -> None:
        """Take the tunable values of ``config`` (``schema`` ``tunable``: task gains, desired normal
        forces, K_V) from the next update on. Everything else must be as this controller's."""
        self.config = config
        self._hand.set_gains(np.array(config.hand.kp), np.array(config.hand.kd))
        for task, contact in zip(self._braces, config.shared.braced_contacts, strict=True):
            task.set_gains(np.array(contact.kp), np.array(contact.kd))
        self.desired_normal_force[:] = [c.desired_normal_force for c in config.shared.braced_contacts]
        self._voltage_gain = self.plant.to_model_order(config.voltage_gain)

    def reset(self) -> None:
        """Forget the targets taken from the first state (a new run starts)."""
        self._hand_trajectory = None
        self._brace_trajectories = []
        self._brace_targets = None
        self._brace_target_lists = []

    def _init_targets(self) -> None:
        """The task paths, from the current positions (after ``computeAllTerms``)."""
        model, data = self._model, self._data
        pin.updateFramePlacements(model, data)
        self._hand_trajectory = self.config.hand.trajectory.build(data.oMf[self._hand.frame].translation.tolist())
        contacts = self.config.shared.braced_contacts
        self._brace_trajectories = [
            c.trajectory.build(data.oMf[t.frame].translation.tolist())
            for c, t in zip(contacts, self._braces, strict=True)
        ]
        # Held braces (the paper's) are sampled once.
        self._braces_held = all(isinstance(b, Hold) for b in self._brace_trajectories)
        self._brace_targets = np.array([b.sample(0.0)[0] for b in self._brace_trajectories], dtype=float).reshape(
            len(self._braces), 3
        )
        self._brace_target_lists = self._brace_targets.tolist()

    def update(self, t: float, q: Vector, dq: Vector) -> ControlOutput:
        """The command for the measured state (q, dq) at time t [s] (model joint order)."""
        model, data = self._model, self._data
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        pin.computeAllTerms(model, data, q, dq)
        if self._hand_trajectory is None:
            self._init_targets()
        assert self._hand_trajectory is not None and self._brace_targets is not None

        # l: PD tasks along the configured axes (eq. 39): every task's translational Jacobian
        # in one matrix, so one product gives the frame velocities and one gives J^T F.
        hand_desired, hand_velocity_desired = self._hand_trajectory.sample(t)
        jacobians = self._task_jacobians
        positions: list[float] = []  # flat: 3 per task
        for task, rows in self._task_rows:
            rows[:] = pin.getFrameJacobian(model, data, task.frame, _WORLD)[:3]
            positions += pin.updateFramePlacement(model, data, task.frame).translation.tolist()
        velocities = jacobians.dot(dq).tolist()
        if self._braces_held:
            brace_targets, brace_velocities = self._brace_target_lists, self._zero_velocities
        else:
            samples = [b.sample(t) for b in self._brace_trajectories]
            self._brace_targets = np.array([position for position, _ in samples]).reshape(len(self._braces), 3)
            brace_targets = self._brace_targets.tolist()
            brace_velocities = [velocity.tolist() for _, velocity in samples]
        targets = [hand_desired.tolist(), *brace_targets]
        target_velocities = [hand_velocity_desired.tolist(), *brace_velocities]
        forces: list[float] = []
        for k, task in enumerate(self._tasks):
            (p0, p1, p2), (d0, d1, d2) = task.kp_list, task.kd_list
            r0, r1, r2 = targets[k]
            a0, a1, a2 = positions[3 * k : 3 * k + 3]
            v0, v1, v2 = target_velocities[k]
            w0, w1, w2 = velocities[3 * k : 3 * k + 3]
            forces += (
                p0 * (r0 - a0) + d0 * (v0 - w0),
                p1 * (r1 - a1) + d1 * (v1 - w1),
                p2 * (r2 - a2) + d2 * (v2 - w2),
            )
        null_input = np.array(forces).dot(jacobians)  # sum of J^T F over the tasks
        gravity = None
        if self.config.gravity_compensation:
            gravity = pin.computeGeneralizedGravity(model, data, q)
            null_input += gravity

        damped = False
        p = len(self._braces)
        if self._single_contact:
            torque, damped = self._braced_torque(dq, null_input, forces, velocities[3:6], gravity)
        elif p:
            terms = self.contact_set.evaluate_data(model, data, dq)
            pin.cholesky.decompose(model, data)
            jc = terms.normal_jacobian
            b = np.array([pin.cholesky.solve(model, data, row) for row in jc])  # B = J_c Mc^-1 (Mc symmetric)
            a_matrix = b @ (jc - terms.friction[:, None] * terms.tangent_jacobian).T
            a_vector = b @ (self._nle + self._damping * dq) - terms.drift
            if self._consistent:  # B^# = Mc B^T (B Mc B^T)^-1 = J_c^T (J_c Mc^-1 J_c^T)^-1 (Khatib)
                b_pinv, damped = np.linalg.solve(b @ jc.T, jc).T, False
            else:
                b_pinv, damped = self._pseudo_inverse(b)
            torque = (
                b_pinv @ (a_vector - a_matrix @ self.desired_normal_force) + (self._identity - b_pinv @ b) @ null_input
            )
        else:
            torque = null_input
        command = self._voltage_gain * torque if self._voltage else torque
        actual = np.array(positions).reshape(-1, 3)  # hand, then the braces (a flat list converts faster)
        return ControlOutput(
            command,
            torque,
            hand_desired,
            actual[0],
            self._brace_targets.copy(),
            actual[1:],
            self.desired_normal_force.copy(),
            damped,
        )

    def _braced_torque(
        self, dq: Vector, null_input: Vector, forces: list[float], velocity: list[float], gravity: Vector | None
    ) -> tuple[Vector, bool]:
        """Eq. 38 for one contact (B is a row), from the pass of ``update``: ``forces`` are the
        task forces F of l = J^T F + g (rows of ``_task_jacobians``; ``gravity`` g or None),
        ``velocity`` the brace frame's.

        Why a special case: the general path costs 72 us per update against 20 us here on the
        paper model (p = 1), i.e. ~50 us of a ~740 us lockstep pair step (7%, above the 5% bar).
        test_controller_law checks that both paths give the same torque."""
        model, data = self._model, self._data
        pin.cholesky.decompose(model, data)
        brace_jacobian, jc, bias = self._brace_jacobian, self._work_jc, self._work_bias
        n0, n1, n2 = self._normal_tuple
        np.dot(self._normal, brace_jacobian, out=jc)  # J_c = n^T J
        np.multiply(self._damping, dq, out=bias)
        bias += self._nle  # h + g + Dc dq
        w0, w1, w2 = velocity
        normal_velocity = n0 * w0 + n1 * w1 + n2 * w2
        s0, s1, s2 = w0 - n0 * normal_velocity, w1 - n1 * normal_velocity, w2 - n2 * normal_velocity  # slip
        a0, a1, a2 = pin.getFrameClassicalAcceleration(model, data, self._braces[0].frame, _WORLD).linear.tolist()
        gamma = n0 * a0 + n1 * a1 + n2 * a2
        y = pin.cholesky.solve(model, data, jc)  # B^T = Mc^-1 J_c^T
        # [task Jacobians; h + g + Dc dq] Mc^-1 J_c^T: the brace rows give B J^T, the tasks' give B l.
        products = self._work.dot(y).tolist()
        bias_y = products.pop()
        null_y = sum(map(operator.mul, forces, products))  # B l = F . (J Mc^-1 J_c^T) (+ B g)
        if gravity is not None:
            null_y += float(gravity.dot(y))
        b0, b1, b2 = products[3:6]  # J Mc^-1 J_c^T of the brace
        jc_y = n0 * b0 + n1 * b1 + n2 * b2
        mu = self._friction
        if mu:  # A = B (J_c - mu J_t)^T, J_t = s^T J / sqrt(|s|^2 + eps^2)
            a_matrix = jc_y - mu / math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + self._eps2) * (s0 * b0 + s1 * b1 + s2 * b2)
        else:
            a_matrix = jc_y
        a_vector = bias_y - gamma  # B (h + g + Dc dq) - gamma
        bb = float(y.dot(y))  # B B^T = |B|^2, the square of B's only singular value
        # tau = B^+ (a - A f_nd) + (I - B^+ B) l = l + B^+ ((a - A f_nd) - B l)
        excess = a_vector - a_matrix * float(self.desired_normal_force[0]) - null_y
        if bb > 1e-280:  # |B| > 1e-140: the SVD test of _pseudo_inverse passes (its ratio is 1 for one row)
            torque = y * (excess / bb)  # B^+ = B^T / |B|^2
            torque += null_input
            return torque, False
        # B = 0 (or tiny): the general test, and its damped inverse
        pinv, damped = self._pseudo_inverse(y[None, :])
        return null_input + pinv[:, 0] * excess, damped

    def _pseudo_inverse(self, b: Vector) -> tuple[Vector, bool]:
        """B^+ = B^T (B B^T)^-1, damped (B^T (B B^T + lambda I)^-1) when B is near-singular."""
        gram = b @ b.T
        singular = np.linalg.svd(b, compute_uv=False)
        if singular[-1] > SINGULAR_RATIO * max(singular[0], 1e-300):
            return np.asarray(np.linalg.solve(gram, b).T, dtype=np.float64), False
        lam = self.config.damping_lambda * max(singular[0] ** 2, 1.0)
        return np.asarray(np.linalg.solve(gram + lam * np.eye(gram.shape[0]), b).T, dtype=np.float64), True


def check_task_rank(config: ControllerConfig, plant: Plant, q0: Vector) -> None:
    """Refuse a task direction the arm cannot move along at the start ``q0`` (model order): each
    configured axis (hand axes, then each brace's) must add a rank to the stacked task Jacobian
    within the motions the braced contacts allow (the null space of J_c). ConfigError names the
    first axis that adds none."""
    robot = plant.robot
    robot.compute(np.asarray(q0, dtype=float), np.zeros(robot.nv))
    jc = plant.braced_set.evaluate(np.zeros(robot.nv)).normal_jacobian
    allowed = np.eye(robot.nv) - np.linalg.pinv(jc) @ jc if jc.size else np.eye(robot.nv)
    tasks = [("hand.axes", config.hand.frame, config.hand.axes)]
    tasks += [(f"contacts.{c.name}.brace_axes", c.frame, c.brace_axes) for c in config.shared.braced_contacts]
    rows: list[Vector] = []
    for parameter, frame, axes in tasks:
        jacobian = robot.frame_jacobian(plant.frame_id(frame, parameter))
        for axis in axes:
            candidate = np.array([*rows, jacobian[axis] @ allowed])
            singular = np.linalg.svd(candidate, compute_uv=False)
            if singular[-1] <= 1e-6 * max(singular[0], 1.0):
                raise ConfigError(
                    f"{parameter}: frame {frame!r} cannot move along {'xyz'[axis]} at the start (that direction adds "
                    "no rank to the task Jacobian, within the motions the braced contacts allow); remove the axis"
                )
            rows.append(candidate[-1])
