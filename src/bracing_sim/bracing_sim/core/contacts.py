"""Bracing contacts: robot frames held on planes n . r = c, with Coulomb-like friction.

``evaluate_contacts`` reads one pinocchio pass (``RobotModel.compute``) and stacks, for
all p contacts, the rows of SPEC section 2: j_c = n^T J, gamma = n . (dJ dq), the slip
velocity and its regularised direction, and j_t = J^T (slip direction).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bracing_sim.core.model import RobotModel
from bracing_sim.core.types import Vector


@dataclass(frozen=True)
class PlaneContact:
    """A robot frame held on the plane ``normal . r = offset`` (normal is normalised)."""

    name: str
    frame: str
    normal: Vector
    offset: float = 0.0
    friction: float = 0.0

    def __post_init__(self) -> None:
        normal = np.asarray(self.normal, dtype=float)
        norm = float(np.linalg.norm(normal)) if normal.shape == (3,) else 0.0
        if normal.shape != (3,) or not np.isfinite(norm) or norm < 1e-9:
            raise ValueError(f"contacts.{self.name}.normal: expected a non-zero 3-vector, got {np.ravel(self.normal).tolist()}")
        object.__setattr__(self, "normal", normal / norm)
        if not np.isfinite(self.offset):
            raise ValueError(f"contacts.{self.name}.offset: must be finite")
        if not (np.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"contacts.{self.name}.friction: must be >= 0, got {self.friction}")


@dataclass
class ContactTerms:
    """Stacked contact quantities at one state (p rows; p may be 0)."""

    positions: Vector  # (p, 3) contact points, world [m]
    jacobians: Vector  # (p, 3, n) translational Jacobians, world axes
    normal_jacobian: Vector  # J_c (p, n): rows n_j^T J_j
    tangent_jacobian: Vector  # J_t (p, n): rows J_j^T s_j / sqrt(|s_j|^2 + eps^2)
    drift: Vector  # gamma (p,): n_j . (dJ_j dq)
    residual: Vector  # C (p,): n_j . r_j - c_j [m]
    slip_velocity: Vector  # (p, 3) tangential velocity of the contact points [m/s]
    slip_direction: Vector  # (p, 3) regularised unit-ish slip direction
    friction: Vector  # mu (p,)
    normals: Vector  # (p, 3)

    @property
    def count(self) -> int:
        return int(self.residual.size)


@dataclass
class ContactSet:
    """The contacts of one robot, with their frames resolved once."""

    robot: RobotModel
    contacts: Sequence[PlaneContact]
    slip_epsilon: float = 1e-4
    frame_ids: list[int] = field(init=False)

    def __post_init__(self) -> None:
        if not self.slip_epsilon > 0.0:
            raise ValueError(f"slip_epsilon: must be > 0, got {self.slip_epsilon}")
        self.frame_ids = [self.robot.frame_id(c.frame) for c in self.contacts]
        p, n = len(self.contacts), self.robot.nv
        self._normals = np.array([c.normal for c in self.contacts], dtype=float).reshape(p, 3)
        self._offsets = np.array([c.offset for c in self.contacts], dtype=float)
        self._friction = np.array([c.friction for c in self.contacts], dtype=float)
        self._tangent_projectors = np.array([np.eye(3) - np.outer(m, m) for m in self._normals]).reshape(p, 3, 3)
        self._jacobians = np.zeros((p, 3, n))
        self._positions = np.zeros((p, 3))
        self._drift_vectors = np.zeros((p, 3))

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.contacts]

    def __len__(self) -> int:
        return len(self.contacts)

    def evaluate(self, dq: Vector) -> ContactTerms:
        """Contact terms from the robot's last ``compute(q, dq)`` pass."""
        robot = self.robot
        for j, frame in enumerate(self.frame_ids):
            self._positions[j] = robot.frame_position(frame)
            self._jacobians[j] = robot.frame_jacobian(frame)
            self._drift_vectors[j] = robot.frame_drift(frame)
        normals = self._normals
        jacobians = self._jacobians.copy()
        positions = self._positions.copy()
        velocity = jacobians @ dq  # (p, 3)
        slip = np.einsum("pij,pj->pi", self._tangent_projectors, velocity)
        slip_norm = np.sqrt(np.einsum("pi,pi->p", slip, slip) + self.slip_epsilon**2)
        direction = slip / slip_norm[:, None]
        return ContactTerms(
            positions=positions,
            jacobians=jacobians,
            normal_jacobian=np.einsum("pi,pin->pn", normals, jacobians),
            tangent_jacobian=np.einsum("pi,pin->pn", direction, jacobians),
            drift=np.einsum("pi,pi->p", normals, self._drift_vectors),
            residual=np.einsum("pi,pi->p", normals, positions) - self._offsets,
            slip_velocity=slip,
            slip_direction=direction,
            friction=self._friction,
            normals=normals,
        )
