"""Typed configuration of a contact (its surface, and for a braced contact the controller's force and brace
task) and of a task's desired path, from the schema's typed values."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bracing_core.contacts import Contact, Cylinder, Plane, Sphere, Surface
from bracing_core.params import ConfigError
from bracing_core.schema import Section
from bracing_core.trajectory import TrajectoryConfig

AXES = ("x", "y", "z")


def axes_indices(name: str, axes: Sequence[str]) -> tuple[int, ...]:
    for axis in axes:
        if axis not in AXES:
            raise ConfigError(f"{name}: axes must be among x, y, z, got {list(axes)}")
    if len(set(axes)) != len(axes):
        raise ConfigError(f"{name}: duplicate axes in {list(axes)}")
    return tuple(AXES.index(a) for a in axes)


def trajectory_from_values(prefix: str, path: Section, point: Sequence[float] | None) -> TrajectoryConfig:
    """A task's path from its typed values (``schema.trajectory_params(prefix, ...)``: ``values.hand.trajectory``,
    a contact's ``trajectory``); ``point``: the held point (hold), or None for the first measured position."""
    plane = axes_indices(prefix + "plane", path.plane)
    direction = path.direction
    kind = path.type
    if kind == "circle" and direction not in (-1.0, 1.0):
        raise ConfigError(f"{prefix}direction: expected +1 or -1, got {direction}")
    flat = path.waypoints or ()
    if kind == "waypoints" and len(flat) % 3:
        raise ConfigError(f"{prefix}waypoints: expected x, y, z per waypoint (a multiple of 3 values), got {len(flat)}")
    center = path.center or (0.0, 0.0, 0.0)
    return TrajectoryConfig(
        kind=kind,
        center=(center[0], center[1], center[2]),
        radius=path.radius or 0.0,
        period=path.period,
        direction=direction,
        phase=path.phase,
        plane=(plane[0], plane[1]),
        point=(point[0], point[1], point[2]) if point else None,
        waypoints=tuple((flat[k], flat[k + 1], flat[k + 2]) for k in range(0, len(flat) - 2, 3)),
        segment_time=path.segment_time,
        start_ramp=path.start_ramp,
    )


def surface_from_values(key: str, own: Section) -> Surface:
    """contacts.<name>: its surface (plane, sphere or cylinder), checked; errors name the parameter."""
    kind = own.surface
    if kind != "plane" and not own.radius > 0.0:
        raise ConfigError(f"{key}radius: a {kind} needs a radius > 0 m, got {own.radius}")
    for name, vector in (("normal", own.normal), ("axis", own.axis)):
        if float(np.linalg.norm(vector)) < 1e-9:
            raise ConfigError(f"{key}{name}: must be a non-zero vector, got {list(vector)}")
    if kind == "sphere":
        return Sphere(np.array(own.center), own.radius, own.inside)
    if kind == "cylinder":
        if isinstance(own.point, str):
            raise ConfigError(
                f"{key}point: a cylinder surface's point is a point on its axis (3 numbers); point: "
                f"{own.point} is for a plane or a sphere (coal measures no link shape against a cylinder surface)"
            )
        return Cylinder(np.array(own.point), np.array(own.axis), own.radius, own.inside)
    return Plane(np.array(own.normal), own.offset)


@dataclass(frozen=True)
class ContactConfig:
    """contacts.<name>: the surface, and for a braced contact the controller's force and brace task.

    A contact without a desired normal force is an obstacle: unilateral, it only pushes.
    """

    name: str
    frame: str
    surface: Surface
    friction: float  # mu
    friction_model: str  # coulomb | regularized
    desired_normal_force: float | None  # f_nd [N]; None: an obstacle
    brace_axes: tuple[int, ...]  # world axis indices of the brace task
    kp: tuple[float, ...]  # one per brace axis
    kd: tuple[float, ...]
    target: tuple[float, float, float] | None  # None: the brace point's initial position
    trajectory: TrajectoryConfig  # the brace point's path (hold: target)
    unilateral: bool = False  # the surface only pushes: release and touchdown (bilateral: the paper)
    feedback_kp: float = 0.0  # force_feedback.kp (dimensionless); 0 0: the paper's feed-forward law
    feedback_ki: float = 0.0  # force_feedback.ki [1/s]
    feedback_topic: str = ""  # force_feedback.topic: a WrenchStamped in world axes; empty = contact_wrench/<name>
    ki: tuple[float, ...] = ()  # one per brace axis; empty: no integral action
    point: str = "frame"  # frame: the frame's origin; geometry: its link's shapes' point nearest the surface

    @property
    def braced(self) -> bool:
        return self.desired_normal_force is not None

    @classmethod
    def from_values(cls, name: str, own: Section, bracing: bool = True) -> ContactConfig:
        """From the typed values of contacts.<name> (``schema.read``'s ``contacts[name]``; the fields a node does
        not read hold their defaults). ``bracing`` False: an obstacle whatever the file says (no force, no brace
        task)."""
        key = f"contacts.{name}."
        desired = own.desired_normal_force if bracing else None
        brace_axes = axes_indices(key + "brace_axes", own.brace_axes) if desired is not None else ()
        if desired is None and bracing and own.brace_axes:
            raise ConfigError(
                f"{key}brace_axes: contact {name!r} has no desired_normal_force, so it is an obstacle with no brace "
                "task; give it a desired_normal_force or remove its brace_axes"
            )
        target = own.target
        feedback = (own.force_feedback.kp or 0.0, own.force_feedback.ki or 0.0)
        if desired is None and bracing and any(feedback):
            raise ConfigError(
                f"{key}force_feedback: contact {name!r} has no desired_normal_force, so no force to feed back; "
                "give it a desired_normal_force or set its force_feedback gains to 0"
            )
        return cls(
            name=name,
            frame=own.frame,
            surface=surface_from_values(key, own),
            friction=own.friction,
            friction_model=own.friction_model,
            desired_normal_force=desired,
            brace_axes=brace_axes,
            kp=tuple(own.kp) if desired is not None else (),
            kd=tuple(own.kd) if desired is not None else (),
            target=(target[0], target[1], target[2]) if target else None,
            trajectory=trajectory_from_values("trajectory.", own.trajectory, target),
            unilateral=own.unilateral or desired is None,
            feedback_kp=feedback[0] if desired is not None else 0.0,
            feedback_ki=feedback[1] if desired is not None else 0.0,
            feedback_topic=own.force_feedback.topic or f"contact_wrench/{name}",
            ki=tuple(own.ki or ()) if desired is not None else (),
            point=own.point if isinstance(own.point, str) else "frame",
        )

    def contact(self, enforced: bool = True) -> Contact:
        """The core's contact; not ``enforced``: only watched (free space)."""
        unilateral = self.unilateral or not enforced
        return Contact(
            self.name, self.frame, self.surface, self.friction, unilateral, enforced, self.friction_model, self.point
        )
