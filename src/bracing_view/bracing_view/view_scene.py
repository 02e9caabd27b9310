"""What bracing-view draws of the surfaces, the kept-out contacts and the links inside a surface (rerun
items, no rclpy).

Each surface is drawn once (``SurfaceSet``): a kept-out frame's or link's contact (``<frame>@<contact>``,
``bracing_core.contact_roles``) is on its owner's surface, and two contacts on the same known surface (two
elbows on one floor) share it. A link inside a surface (``link_penetration``, robot.collision_geometry)
is marked at its deepest point: a red point, a line from it to the surface, and its name and depth.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from bracing_analysis.surfaces import Shape, shape_of
from bracing_core.contact_roles import surface_owner
from bracing_core.kinematics import z_to
from bracing_recorder.scene import SURFACE_PATCH_M

SURFACE_COLOR = [120, 120, 120, 90]  # grey, see-through: the arm stays visible behind a surface
INSIDE_COLOR = [230, 0, 0]  # a link inside a surface: red, as a contact point that holds
PENETRATION_PATH = "world/link_penetration"


def surface_item(shape: Shape | None, on_surface: np.ndarray, normal: np.ndarray) -> Any:
    """A contact's surface as the recorder's markers draw it (``scene``): a sphere or a cylinder of
    known geometry whole (a cylinder SURFACE_PATCH_M long, centred nearest ``on_surface``), anything
    else as the square patch of its tangent plane at ``on_surface``, SURFACE_PATCH_M a side."""
    if shape is not None and shape.curved and shape.radius > 0.0:
        if shape.kind == "sphere":
            radii = [[shape.radius] * 3]
            return rr.Ellipsoids3D(centers=[shape.center], half_sizes=radii, colors=[SURFACE_COLOR], fill_mode="solid")
        point, axis = np.array(shape.point), np.array(shape.axis)
        centre = point + float(np.dot(on_surface - point, axis)) * axis
        return rr.Cylinders3D(
            lengths=[SURFACE_PATCH_M],
            radii=[shape.radius],
            centers=[centre],
            quaternions=[rr.Quaternion(xyzw=z_to(axis))],
            colors=[SURFACE_COLOR],
            fill_mode="solid",
        )
    half = [0.5 * SURFACE_PATCH_M, 0.5 * SURFACE_PATCH_M, 0.001]
    turn = rr.Quaternion(xyzw=z_to(normal))  # the patch's thin z onto the normal
    return rr.Boxes3D(
        centers=[on_surface - 0.001 * normal], half_sizes=[half], quaternions=[turn], colors=[SURFACE_COLOR]
    )


class SurfaceSet:
    """The surfaces drawn so far: each owner contact's once, and a known shape once whatever owns it."""

    def __init__(self, shapes: Mapping[str, Shape]) -> None:
        self.shapes = shapes
        self._owners: set[str] = set()
        self._shapes: set[Shape] = set()

    def first(self, contact: str, point: np.ndarray, residual: float, normal: np.ndarray) -> tuple[str, Any] | None:
        """(entity path, item) of the surface of ``contact`` (at ``point`` [m], ``residual`` [m] off it along
        ``normal``) if it is not drawn yet; None if it is."""
        owner = surface_owner(contact)
        if owner in self._owners:
            return None
        self._owners.add(owner)
        shape = shape_of(self.shapes, contact)
        if shape is not None:
            if shape in self._shapes:
                return None
            self._shapes.add(shape)
        return f"world/surfaces/{owner}", surface_item(shape, point - residual * normal, normal)


def penetration_items(state: Any) -> list[tuple[str, Any]]:
    """One ``link_penetration`` entry (a ContactState: the link deepest in or nearest to a surface) as
    (entity path, item) pairs under the surface's path: its deepest point, labelled with the link and the
    depth, and a line from it to the surface; a Clear of them while no link is inside that surface."""
    owner = surface_owner(str(state.name))
    path = f"{PENETRATION_PATH}/{owner}"
    if not state.active:
        return [(path, rr.Clear(recursive=True))]
    deepest = np.array([state.position.x, state.position.y, state.position.z], dtype=float)
    normal = np.array([state.normal.x, state.normal.y, state.normal.z], dtype=float)
    depth = -float(state.residual)  # [m], the signed distance is negative inside
    label = f"{state.frame} {1000.0 * depth:.0f} mm inside {owner}"
    return [
        (f"{path}/deepest", rr.Points3D([deepest], radii=0.015, colors=[INSIDE_COLOR], labels=[label])),
        (f"{path}/depth", rr.LineStrips3D([[deepest, deepest + depth * normal]], radii=0.004, colors=[INSIDE_COLOR])),
    ]
