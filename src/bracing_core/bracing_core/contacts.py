"""Contacts: robot frames held on surfaces C(r) = 0 (planes, spheres, cylinders), with friction.

Each surface gives, at a point r, the signed distance C(r) (positive on the side the robot
stays on), its unit gradient n(r) = dC/dr (the direction the surface pushes) and its
Hessian H_C(r) (zero for a plane). ``ContactSet.evaluate_data`` reads one pinocchio pass
(``RobotModel.compute``) and stacks, for all p contacts, the rows of docs/model.md
(Contacts): j_c = n^T J, gamma = n . (dJ dq) + (J dq)^T H_C (J dq), the slip velocity
(the part of J dq in the tangent plane) and its regularised direction, j_t = J^T (slip direction).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from bracing_core.model import RobotModel
from bracing_core.types import Vector

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_NO_CURVATURE = np.zeros((3, 3))


def _vector(value: Sequence[float] | Vector, what: str, unit: bool = False) -> Vector:
    array = np.asarray(value, dtype=float)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{what}: expected 3 finite numbers, got {np.ravel(value).tolist()}")
    if unit:
        norm = float(np.linalg.norm(array))
        if norm < 1e-9:
            raise ValueError(f"{what}: expected a non-zero 3-vector, got {array.tolist()}")
        array = array / norm
    return array


def _radius(value: float, what: str) -> float:
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{what}: must be > 0 m, got {value}")
    return float(value)


@dataclass(frozen=True)
class Plane:
    """C = n . r - offset (n normalised): the half-space n . r >= offset is free."""

    normal: Vector
    offset: float = 0.0
    kind = "plane"

    def __post_init__(self) -> None:
        object.__setattr__(self, "normal", _vector(self.normal, "normal", unit=True))
        if not np.isfinite(self.offset):
            raise ValueError("offset: must be finite")

    def evaluate(self, point: Vector) -> tuple[float, Vector, Vector]:
        """(C, n, H_C) at ``point``."""
        return float(self.normal.dot(point)) - self.offset, self.normal, _NO_CURVATURE


@dataclass(frozen=True)
class Sphere:
    """C = |r - center| - radius: the frame stays outside (``inside``: C = radius - |r - center|)."""

    center: Vector
    radius: float
    inside: bool = False
    kind = "sphere"

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vector(self.center, "center"))
        object.__setattr__(self, "radius", _radius(self.radius, "radius"))

    def evaluate(self, point: Vector) -> tuple[float, Vector, Vector]:
        return _round_surface(np.asarray(point) - self.center, np.eye(3), self.radius, self.inside)


@dataclass(frozen=True)
class Cylinder:
    """An infinite cylinder about the line through ``point`` along ``axis``:
    C = |(I - a a^T)(r - point)| - radius, outside (``inside`` flips the sign)."""

    point: Vector
    axis: Vector
    radius: float
    inside: bool = False
    kind = "cylinder"

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _vector(self.point, "point"))
        object.__setattr__(self, "axis", _vector(self.axis, "axis", unit=True))
        object.__setattr__(self, "radius", _radius(self.radius, "radius"))
        object.__setattr__(self, "_projector", np.eye(3) - np.outer(self.axis, self.axis))

    def evaluate(self, point: Vector) -> tuple[float, Vector, Vector]:
        projector = self._projector  # type: ignore[attr-defined]
        return _round_surface(projector.dot(np.asarray(point) - self.point), projector, self.radius, self.inside)


def _round_surface(offset: Vector, projector: Vector, radius: float, inside: bool) -> tuple[float, Vector, Vector]:
    """(C, n, H_C) of a sphere (projector I) or cylinder (projector I - a a^T) from the point's
    offset from the centre (line), already projected: with d = |offset|, n = offset / d and
    H_C = (projector - n n^T) / d; inside, all three change sign."""
    distance = float(np.linalg.norm(offset))
    if distance < 1e-12:
        raise ValueError("a contact point is at the centre of its sphere or on the axis of its cylinder")
    normal = offset / distance
    hessian = (projector - np.outer(normal, normal)) / distance
    if inside:
        return radius - distance, -normal, -hessian
    return distance - radius, normal, hessian


Surface = Plane | Sphere | Cylinder


@dataclass(frozen=True)
class Contact:
    """A robot frame held on a surface.

    Bilateral (the paper): the surface holds the frame both ways. Unilateral: it only
    pushes; the contact releases when the force would pull and lands again at touchdown.
    ``enforced`` False: the surface is only watched (the residual is reported, never a
    force), as in the free-space comparison where the surfaces are removed.
    """

    name: str
    frame: str
    surface: Surface
    friction: float = 0.0
    unilateral: bool = False
    enforced: bool = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"contacts.{self.name}.friction: must be >= 0, got {self.friction}")
        if not self.enforced and not self.unilateral:
            raise ValueError(f"contacts.{self.name}: a contact that is only watched must be unilateral")


@dataclass
class ContactTerms:
    """Stacked contact quantities at one state (p rows; p may be 0)."""

    positions: Vector  # (p, 3) contact points, world [m]
    jacobians: Vector  # (p, 3, n) translational Jacobians, world axes
    normal_jacobian: Vector  # J_c (p, n): rows n_j^T J_j
    tangent_jacobian: Vector  # J_t (p, n): rows J_j^T s_j / sqrt(|s_j|^2 + eps^2)
    drift: Vector  # gamma (p,): n_j . (dJ_j dq) + v_j^T H_j v_j
    residual: Vector  # C (p,): signed distance to the surface [m]
    slip_velocity: Vector  # (p, 3) tangential velocity of the contact points [m/s]
    slip_direction: Vector  # (p, 3) regularised unit-ish slip direction
    friction: Vector  # mu (p,)
    normals: Vector  # (p, 3) surface normals n(r) at the contact points

    @property
    def count(self) -> int:
        return int(self.residual.size)


@dataclass
class ContactSet:
    """The contacts of one robot, with their frames resolved once."""

    robot: RobotModel
    contacts: Sequence[Contact]
    slip_epsilon: float = 1e-4
    frame_ids: list[int] = field(init=False)

    def __post_init__(self) -> None:
        if not self.slip_epsilon > 0.0:
            raise ValueError(f"slip_epsilon: must be > 0, got {self.slip_epsilon}")
        self.frame_ids = [self.robot.frame_id(c.frame) for c in self.contacts]
        p = len(self.contacts)
        # Constant normals of the planes (a curved surface's row is its normal at the last evaluation).
        self.normals = np.array(
            [c.surface.normal if isinstance(c.surface, Plane) else (0.0, 0.0, 1.0) for c in self.contacts], dtype=float
        ).reshape(p, 3)
        self.planar = [isinstance(c.surface, Plane) for c in self.contacts]
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
        normals = np.empty((p, 3))
        residual = np.empty(p)
        drift = np.empty(p)
        for j, (frame, contact) in enumerate(zip(self.frame_ids, self.contacts, strict=True)):
            positions[j] = pin.updateFramePlacement(model, data, frame).translation
            jacobians[j] = pin.getFrameJacobian(model, data, frame, _WORLD)[:3]
            acceleration = pin.getFrameClassicalAcceleration(model, data, frame, _WORLD).linear
            residual[j], normals[j], hessian = contact.surface.evaluate(positions[j])
            velocity = jacobians[j].dot(dq)
            drift[j] = normals[j].dot(acceleration) + velocity.dot(hessian).dot(velocity)
        velocity = jacobians @ dq  # (p, 3)
        slip = velocity - normals * (normals * velocity).sum(axis=1)[:, None]  # tangential part
        slip_norm = np.sqrt((slip * slip).sum(axis=1) + self.slip_epsilon**2)
        direction = slip / slip_norm[:, None]
        return ContactTerms(
            positions=positions,
            jacobians=jacobians,
            normal_jacobian=np.matmul(normals[:, None, :], jacobians)[:, 0, :],
            tangent_jacobian=np.matmul(direction[:, None, :], jacobians)[:, 0, :],
            drift=drift,
            residual=residual,
            slip_velocity=slip,
            slip_direction=direction,
            friction=self.friction,
            normals=normals,
        )
