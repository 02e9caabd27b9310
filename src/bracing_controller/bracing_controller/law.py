"""The decoupled force/position law of SPEC section 2 (paper eqs. 36-41), no ROS.

    B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
    tau = B^+ (a - A f_nd) + (I - B^+ B) l
    l = sum_j J_j^T [Kp_j (r_dj - r_j) + Kd_j (dr_dj - dr_j)] + J_h^T [Kp_h (r_dh - r_h) + Kd_h (dr_dh - dr_h)]
    v = K_V tau                                   (voltage mode; tau itself in torque mode)

Each task uses only the world axes the configuration names. With no contacts, tau = l.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bracing_controller.config import ControllerConfig
from bracing_controller.trajectory import Circle, Hold, Trajectory
from bracing_sim.config import Plant
from bracing_sim.core.dynamics import InputMode
from bracing_sim.core.types import Vector

# Smallest singular value of B (relative to its largest) below which B^+ is damped.
SINGULAR_RATIO = 1e-8


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


class DecoupledController:
    """One control update per measured state; the same object runs in the node and in tests."""

    def __init__(self, config: ControllerConfig, plant: Plant | None = None) -> None:
        self.config = config
        self.plant = plant if plant is not None else Plant(config.shared)
        robot = self.plant.robot
        self.robot = robot
        self.contact_set = self.plant.contact_set
        self.mode = config.shared.input_mode
        motors = self.plant.motors
        voltage = self.mode is InputMode.VOLTAGE
        self._added_inertia = motors.reflected_inertia if voltage else np.zeros(robot.nv)
        self._damping = robot.damping + (motors.reflected_damping if voltage else 0.0)
        self._voltage_gain = self.plant.to_model_order(config.voltage_gain)
        contacts = config.shared.contacts
        self.desired_normal_force = np.array([c.desired_normal_force for c in contacts], dtype=float)
        hand = config.hand
        self._hand = _Task(robot.frame_id(hand.frame), np.eye(3)[list(hand.axes)], np.array(hand.kp), np.array(hand.kd))
        self._braces = [
            _Task(fid, np.eye(3)[list(c.brace_axes)], np.array(c.kp), np.array(c.kd))
            for fid, c in zip(self.contact_set.frame_ids, contacts, strict=True)
        ]
        # Targets that default to the first measured state.
        self._hand_trajectory: Trajectory | None = None
        self._brace_targets: Vector | None = None
        self._identity = np.eye(robot.nv)

    def reset(self) -> None:
        """Forget the targets taken from the first state (a new run starts)."""
        self._hand_trajectory = None
        self._brace_targets = None

    def _init_targets(self) -> None:
        robot, cfg = self.robot, self.config.hand.trajectory
        if cfg.kind == "circle":
            self._hand_trajectory = Circle(cfg.center, cfg.radius, cfg.period, cfg.direction, cfg.phase, cfg.plane)
        else:
            point = cfg.point if cfg.point is not None else tuple(robot.frame_position(self._hand.frame))
            self._hand_trajectory = Hold((float(point[0]), float(point[1]), float(point[2])))
        self._brace_targets = np.array(
            [c.target if c.target is not None else robot.frame_position(t.frame)
             for c, t in zip(self.config.shared.contacts, self._braces, strict=True)],
            dtype=float,
        ).reshape(len(self._braces), 3)

    def update(self, t: float, q: Vector, dq: Vector) -> ControlOutput:
        """The command for the measured state (q, dq) at time t [s] (model joint order)."""
        robot = self.robot
        robot.compute(q, dq)
        if self._hand_trajectory is None:
            self._init_targets()
        assert self._hand_trajectory is not None and self._brace_targets is not None

        # l: PD tasks along the configured axes (eq. 39).
        hand_desired, hand_velocity_desired = self._hand_trajectory.sample(t)
        hand_actual = robot.frame_position(self._hand.frame).copy()
        null_input = self._task_torque(self._hand, hand_desired, hand_velocity_desired, hand_actual, dq)
        brace_actual = np.zeros((len(self._braces), 3))
        for j, task in enumerate(self._braces):
            brace_actual[j] = robot.frame_position(task.frame)
            null_input += self._task_torque(task, self._brace_targets[j], np.zeros(3), brace_actual[j], dq)
        if self.config.gravity_compensation:
            null_input += robot.gravity_torque(q)

        damped = False
        if len(self.contact_set):
            terms = self.contact_set.evaluate(dq)
            mass = robot.mass_matrix().copy()
            mass[np.diag_indices(robot.nv)] += self._added_inertia
            jc = terms.normal_jacobian
            b = np.linalg.solve(mass, jc.T).T  # B = J_c Mc^-1 (Mc symmetric)
            a_matrix = b @ (jc - terms.friction[:, None] * terms.tangent_jacobian).T
            a_vector = b @ (robot.nonlinear_effects() + self._damping * dq) - terms.drift
            b_pinv, damped = self._pseudo_inverse(b)
            torque = b_pinv @ (a_vector - a_matrix @ self.desired_normal_force) + (self._identity - b_pinv @ b) @ null_input
        else:
            torque = null_input
        command = self._voltage_gain * torque if self.mode is InputMode.VOLTAGE else torque
        return ControlOutput(
            command=command,
            torque=torque,
            hand_desired=hand_desired,
            hand_actual=hand_actual,
            brace_desired=self._brace_targets.copy(),
            brace_actual=brace_actual,
            desired_normal_force=self.desired_normal_force.copy(),
            damped=damped,
        )

    def _task_torque(self, task: _Task, desired: Vector, desired_velocity: Vector, actual: Vector, dq: Vector) -> Vector:
        jacobian = self.robot.frame_jacobian(task.frame)
        s = task.selector
        force = task.kp * (s @ (desired - actual)) + task.kd * (s @ (desired_velocity - jacobian @ dq))
        return np.asarray((s @ jacobian).T @ force)

    def _pseudo_inverse(self, b: Vector) -> tuple[Vector, bool]:
        """B^+ = B^T (B B^T)^-1, damped (B^T (B B^T + lambda I)^-1) when B is near-singular."""
        gram = b @ b.T
        singular = np.linalg.svd(b, compute_uv=False)
        if singular[-1] > SINGULAR_RATIO * max(singular[0], 1e-300):
            return np.linalg.solve(gram, b).T, False
        lam = self.config.damping_lambda * max(singular[0] ** 2, 1.0)
        return np.linalg.solve(gram + lam * np.eye(gram.shape[0]), b).T, True
