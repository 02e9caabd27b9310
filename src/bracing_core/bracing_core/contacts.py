"""Bracing contacts: robot frames held on planes n . r = c, with Coulomb-like friction.

``evaluate_contacts`` reads one pinocchio pass (``RobotModel.compute``) and stacks, for
all p contacts, the rows of docs/model.md (Contacts): j_c = n^T J, gamma = n . (dJ dq), the slip
velocity and its regularised direction, and j_t = J^T (slip direction).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from bracing_core.model import RobotModel
from bracing_core.types import Vector

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class PlaneContact:
    """A robot frame held on the plane ``normal . r = offset`` (normal is normalised).

    Bilateral (the paper): the plane holds the frame both ways. Unilateral: it only pushes;
    the contact releases when the force would pull and re-engages at touchdown.
    """

    name: str
    frame: str
    normal: Vector
    offset: float = 0.0
    friction: float = 0.0
    unilateral: bool = False

    def __post_init__(self) -> None:
        normal = np.asarray(self.normal, dtype=float)
        norm = float(np.linalg.norm(normal)) if normal.shape == (3,) else 0.0
        if normal.shape != (3,) or not np.isfinite(norm) or norm < 1e-9:
            raise ValueError(
                f"contacts.{self.name}.normal: expected a non-zero 3-vector, got {np.ravel(self.normal).tolist()}"
            )
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
        p = len(self.contacts)
        self.normals = np.array([c.normal for c in self.contacts], dtype=float).reshape(p, 3)
        self.offsets = np.array([c.offset for c in self.contacts], dtype=float)
        self.friction = np.array([c.friction for c in self.contacts], dtype=float)

    def subset(self, indices: Sequence[int]) -> ContactSet:
        """The contacts at ``indices`` (in that order), on the same robot."""
        return ContactSet(self.robot, [self.contacts[j] for j in indices], self.slip_epsilon)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.contacts]

    def __len__(self) -> int:
        return len(self.contacts)

    def evaluate(self, dq: Vector) -> ContactTerms:
        """Contact terms from the robot's last ``compute(q, dq)`` pass."""
        return self.evaluate_data(self.robot.model, self.robot.data, dq)

    def evaluate_data(self, model: pin.Model, data: pin.Data, dq: Vector) -> ContactTerms:
        """Contact terms from a pinocchio (model, data) after ``computeAllTerms(q, dq)``.

        ``model`` must be this robot's model or a copy of it (e.g. ``RobotModel.with_armature``):
        the frame ids are the robot's.
        """
        p, n = len(self.frame_ids), self.robot.nv
        positions = np.empty((p, 3))
        jacobians = np.empty((p, 3, n))
        drift_vectors = np.empty((p, 3))
        for j, frame in enumerate(self.frame_ids):
            positions[j] = pin.updateFramePlacement(model, data, frame).translation
            jacobians[j] = pin.getFrameJacobian(model, data, frame, _WORLD)[:3]
            drift_vectors[j] = pin.getFrameClassicalAcceleration(model, data, frame, _WORLD).linear
        normals = self.normals
        velocity = jacobians @ dq  # (p, 3)
        slip = velocity - normals * (normals * velocity).sum(axis=1)[:, None]  # tangential part
        slip_norm = np.sqrt((slip * slip).sum(axis=1) + self.slip_epsilon**2)
        direction = slip / slip_norm[:, None]
        return ContactTerms(
            positions=positions,
            jacobians=jacobians,
            normal_jacobian=np.matmul(normals[:, None, :], jacobians)[:, 0, :],
            tangent_jacobian=np.matmul(direction[:, None, :], jacobians)[:, 0, :],
            drift=(normals * drift_vectors).sum(axis=1),
            residual=(normals * positions).sum(axis=1) - self.offsets,
            slip_velocity=slip,
            slip_direction=direction,
            friction=self.friction,
            normals=normals,
        )
