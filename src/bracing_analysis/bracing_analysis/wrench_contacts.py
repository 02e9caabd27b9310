"""A contact's series from its recorded wrench, for a robot that publishes no ``contacts`` topic.

A ros2_control robot (``bracing-pair --engine mujoco``) reports each contact as
``contact_wrench/<name>`` only. What the summary needs of ``contacts`` is then derived: the normal
force f_n = n . F (F the force on the robot, n the surface's normal at the contact point), the
friction force |F - f_n n|, the residual C (the signed distance of the contact point from its surface:
< 0 is penetration) with the point from the controller's ``brace_actual`` at the same stamp, and the
contact active where f_n > 0. The slip speed is not recorded: slip stays n/a.
"""

from __future__ import annotations

import numpy as np

from bracing_analysis.series import BagSeries, ContactSeries, FloatArray
from bracing_analysis.surfaces import Shape, shape_of

STAMP_DIGITS = 6  # stamps matched to the microsecond (both are the same sim-time stamps, in [s])


def surface_distance(shape: Shape, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(signed distance C [m], unit normal) of each point (rows) to ``shape``; C < 0 inside the surface."""
    if shape.kind == "plane":
        normal = np.asarray(shape.normal, dtype=float)
        return points @ normal - shape.offset, np.tile(normal, (len(points), 1))
    if shape.kind == "sphere":
        radial = points - np.asarray(shape.center, dtype=float)
    else:  # cylinder: the part off its axis
        axis = np.asarray(shape.axis, dtype=float)
        radial = points - np.asarray(shape.point, dtype=float)
        radial = radial - np.outer(radial @ axis, axis)
    length = np.linalg.norm(radial, axis=1)
    normal = radial / np.maximum(length, 1e-12)[:, None]
    sign = -1.0 if shape.inside else 1.0
    return sign * (length - shape.radius), sign * normal


def fill_from_wrench(cs: ContactSeries, shape: Shape) -> None:
    """Fill ``cs``'s contact columns from its wrench and the controller's brace_actual (see the module)."""
    force_keys = np.round(cs.t_force, STAMP_DIGITS)
    ctrl_keys = np.round(cs.t_ctrl, STAMP_DIGITS)
    keys, in_force, in_ctrl = np.intersect1d(force_keys, ctrl_keys, return_indices=True)
    if not keys.size:
        return
    points = cs.brace_actual[in_ctrl]
    residual, normal = surface_distance(shape, points)
    force = cs.force[in_force]
    normal_force = np.einsum("ij,ij->i", force, normal)
    cs.t = cs.t_force[in_force]
    cs.normal_force = normal_force
    cs.friction_force = np.linalg.norm(force - normal_force[:, None] * normal, axis=1)
    cs.residual = residual
    cs.active = normal_force > 0.0
    cs.position = points
    cs.normal = normal
    cs.t_matched = cs.t
    cs.normal_force_error = normal_force - cs.normal_force_desired[in_ctrl]


def contacts_from_wrenches(series: BagSeries) -> list[str]:
    """Fill every contact that has a wrench and controller_state but no ``contacts`` samples (a
    ros2_control robot's bag); the names filled."""
    filled = []
    for name, cs in series.contacts.items():
        shape = shape_of(series.surfaces, name)
        if cs.t.size or not cs.t_force.size or not cs.t_ctrl.size or shape is None:
            continue
        fill_from_wrench(cs, shape)
        filled.append(name)
    return filled
