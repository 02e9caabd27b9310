"""Each link's deepest inside the contact surfaces over a recorded run (summary.json ``link_penetration_max_m``).

The simulator's ``link_penetration`` topic carries, per surface, only the link deepest into it at each state; the
summary has every moving link with collision shapes. It measures them again from the bag: the URDF as simulated
(``robot_description``, meshes as file:// paths), every recorded posture (``joint_states``) and the surfaces (the
bag's metadata), by the engine's own measurement (``bracing_engine.Dynamics.measure_links``, coal), the one the
simulator ran. No rclpy; the engine is imported only when a run has the topic.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bracing_analysis.surfaces import Shape


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
    import bracing_engine as engine

    surfaces = [_engine_surface(engine, shape) for shape in measurable(shapes)]
    if not surfaces or not len(positions):
        return {}
    with tempfile.TemporaryDirectory(prefix="bracing-links-") as folder:
        urdf = Path(folder) / "robot.urdf"
        urdf.write_text(description, encoding="utf-8")
        n = len(joint_names)
        zeros = np.zeros(n)
        drive = engine.Drive(False, zeros, zeros, zeros, zeros, zeros, zeros, False, zeros, zeros, 20.0, 0.0)
        # by keyword: the shapes are collision_description's (urdf_xml and a drive's wheels come before it)
        robot = engine.Robot(str(urdf), np.zeros(3), [], [], 1.0, collision_description=description)
        dynamics = engine.Dynamics(robot, drive, [], 1e-4, 0.0)
    order = [list(joint_names).index(name) for name in dynamics.joint_names]
    links = list(dynamics.measure_links(zeros, surfaces).links)
    deepest = np.zeros(len(links))
    for q in np.asarray(positions, dtype=float)[:, order]:
        distance = dynamics.measure_links(q, surfaces).distance.reshape(len(surfaces), len(links))
        np.maximum(deepest, -distance.min(axis=0), out=deepest)
    return dict(zip(links, deepest.tolist(), strict=True))


def _engine_surface(engine: Any, shape: Shape) -> Any:
    if shape.kind == "plane":
        return engine.Surface.plane(np.array(shape.normal), shape.offset)
    return engine.Surface.sphere(np.array(shape.center), shape.radius, False)
