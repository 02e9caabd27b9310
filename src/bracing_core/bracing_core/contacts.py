"""Contacts: robot frames held on surfaces C(r) = 0 (planes, spheres, cylinders), with friction.

Each surface gives, at a point r, the signed distance C(r) (positive on the side the robot
stays on), its unit gradient n(r) = dC/dr (the direction the surface pushes) and its
Hessian H_C(r) (zero for a plane). The engine evaluates them (bracing_engine Surface) and
stacks, for all p contacts, the rows of docs/model.md (Contacts) into its ``Answer``:
j_c = n^T J, gamma = n . (dJ dq) + (J dq)^T H_C (J dq), the slip velocity (the part of J dq in
the tangent plane) and its regularised direction, j_t = J^T (slip direction). This module
describes the surfaces and contacts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bracing_core.model import RobotModel
from bracing_core.types import Vector


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


def _replace_checked(surface: object, **values: object) -> None:
    """A frozen surface's fields set to their checked values (in its ``__post_init__``)."""
    for name, value in values.items():
        object.__setattr__(surface, name, value)


@dataclass(frozen=True)
class Plane:
    """C = n . r - offset (n normalised): the half-space n . r >= offset is free."""

    normal: Vector
    offset: float = 0.0
    kind = "plane"

    def __post_init__(self) -> None:
        _replace_checked(self, normal=_vector(self.normal, "normal", unit=True))
        if not np.isfinite(self.offset):
            raise ValueError("offset: must be finite")


@dataclass(frozen=True)
class Sphere:
    """C = |r - center| - radius: the frame stays outside (``inside``: C = radius - |r - center|)."""

    center: Vector
    radius: float
    inside: bool = False
    kind = "sphere"

    def __post_init__(self) -> None:
        _replace_checked(self, center=_vector(self.center, "center"), radius=_radius(self.radius, "radius"))


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
        point, axis = _vector(self.point, "point"), _vector(self.axis, "axis", unit=True)
        _replace_checked(self, point=point, axis=axis, radius=_radius(self.radius, "radius"))


Surface = Plane | Sphere | Cylinder
FRICTION_MODELS = ("coulomb", "regularized")
CONTACT_POINTS = ("frame", "geometry")


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
    # coulomb: stick held as a constraint inside the cone |f_t| <= mu |f_n|, slide with |f_t| = mu |f_n|
    # against the slip; regularized: the paper's f_t = mu f_n s / sqrt(|s|^2 + eps^2)
    friction_model: str = "coulomb"
    # frame: the frame's origin; geometry: the point of the frame's link's collision shapes nearest the surface
    # (the engine finds it at every evaluation)
    point: str = "frame"

    def __post_init__(self) -> None:
        if self.point not in CONTACT_POINTS:
            raise ValueError(
                f"contacts.{self.name}.point: expected one of {', '.join(CONTACT_POINTS)}, got {self.point!r}"
            )
        if self.friction_model not in FRICTION_MODELS:
            raise ValueError(
                f"contacts.{self.name}.friction_model: expected one of {', '.join(FRICTION_MODELS)}, "
                f"got {self.friction_model!r}"
            )
        if not (np.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"contacts.{self.name}.friction: must be >= 0, got {self.friction}")
        if not self.enforced and not self.unilateral:
            raise ValueError(f"contacts.{self.name}: a contact that is only watched must be unilateral")


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
        self.friction = np.array([c.friction for c in self.contacts], dtype=float)

    def subset(self, indices: Sequence[int]) -> ContactSet:
        """The contacts at ``indices`` (in that order), on the same robot."""
        return ContactSet(self.robot, [self.contacts[j] for j in indices], self.slip_epsilon)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.contacts]

    def __len__(self) -> int:
        return len(self.contacts)
