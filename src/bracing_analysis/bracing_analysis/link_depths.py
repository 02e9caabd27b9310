"""Each link's deepest inside the contact surfaces over a recorded run (summary.json ``link_penetration_max_m``).

The simulator's ``link_penetration`` topic carries, per surface, only the link deepest into it at each state; the
summary has every moving link with collision shapes. It measures them again from the bag: the URDF as simulated
(``robot_description``, meshes as file:// paths), every recorded posture (``joint_states``) and the surfaces (the
bag's metadata), by the engine's own measurement (coal, through
``bracing_core.link_penetration.deepest_over_postures``), the one the simulator ran. No rclpy; the engine is
imported only when a run has the topic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from bracing_analysis.surfaces import Shape
from bracing_core.contacts import Plane, Sphere


def measurable(shapes: Mapping[str, Shape]) -> list[Shape]:
    """The distinct surfaces the links' shapes are measured against (planes and the outside of spheres)."""
    out: list[Shape] = []
    for shape in shapes.values():
        if (shape.kind == "plane" or (shape.kind == "sphere" and not shape.inside)) and shape not in out:
            out.append(shape)
    return out


def every_link_deepest(
    description: str, joint_names: Sequence[str], positions: NDArray[np.float64], shapes: Mapping[str, Shape]
) -> dict[str, float]:
    """{link: the deepest it went inside any of ``shapes`` [m] (0: never)} over ``positions`` (rows: postures,
    columns: ``joint_names``), every moving link of ``description`` with collision shapes. ValueError if the
    engine cannot load them (a mesh not on this machine)."""
    from bracing_core.link_penetration import deepest_over_postures  # the engine: only for a run with the topic

    surfaces = [_core_surface(shape) for shape in measurable(shapes)]
    return deepest_over_postures(description, joint_names, positions, surfaces)


def _core_surface(shape: Shape) -> Plane | Sphere:
    if shape.kind == "plane":
        return Plane(np.array(shape.normal), shape.offset)
    return Sphere(np.array(shape.center), shape.radius, False)
