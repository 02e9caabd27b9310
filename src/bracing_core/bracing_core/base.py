"""The robot as the engine integrates it: one position per velocity (nq == nv), a mobile root if asked.

pinocchio reads a URDF ``continuous`` joint as its unbounded revolute joint (nq 2: cos and sin of the
angle, nv 1) and a ``planar`` joint as nq 4 (x, y, cos, sin), nv 3 (velocities in the moving frame).
The engine, the rollout and the packed state (one q, dq, current and temperature per joint) carry
one position per velocity, so ``chart_urdf`` rewrites the URDF text to a global chart of the covering
space, with the same dynamics:

- a ``continuous`` joint becomes a ``revolute`` joint about the same axis without limits (pinocchio's
  "no limit", the largest double: urdfdom reads no ``inf``). The unbounded revolute's motion subspace
  is the revolute's, so M, h + g and every Jacobian are the same numbers bit for bit; the angle is
  the unwrapped one JointState carries.
- a planar root (``robot.base: planar | diff_drive``, or a URDF ``planar`` joint whose parent is the
  URDF's root link) becomes three joints named ``base_x``, ``base_y`` (prismatic along the world's x
  and y) and ``base_yaw`` (revolute about z, no limits) with massless links between them: their
  velocities are the root's world-frame velocities (x', y', yaw rate), not pinocchio's planar joint's
  body-frame ones; the configuration space is the same plane times the unwrapped yaw, without the
  normalisation drift of (cos, sin) and without a singular chart.

A URDF without continuous joints and with ``robot.base: fixed`` comes back unchanged (the same text),
so every fixed-base robot is loaded exactly as before.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from bracing_core.motors import FIELDS, MotorParams

if TYPE_CHECKING:
    from bracing_core.schema import Section

BASES = ("fixed", "planar", "diff_drive")
BASE_JOINTS = ("base_x", "base_y", "base_yaw")
ODOM_LINK = "odom"  # the added root (the plane the base moves in), named as ROS names that frame
NO_LIMIT = "1.7976931348623157e+308"  # pinocchio's position, effort and velocity "no limit"


class BaseError(ValueError):
    """A URDF or a base setting that the chart cannot express; the message says what to set."""


def chart_urdf(urdf_xml: str, base: str = "fixed", source: str = "robot.urdf") -> str:
    """``urdf_xml`` with continuous joints as unlimited revolute ones and the planar root as three joints
    (see the module docstring); the text itself when there is nothing to rewrite."""
    if base not in BASES:
        raise BaseError(f"robot.base: {base!r} is not one of {', '.join(BASES)}")
    try:
        robot = ET.fromstring(urdf_xml)
    except ET.ParseError as exc:
        raise BaseError(f"{source}: cannot read the URDF: {exc}") from exc
    joints = robot.findall("joint")
    root = _root_link(robot, source)
    planar = [j for j in joints if j.get("type") == "planar"]
    floating = [j for j in joints if j.get("type") == "floating"]
    continuous = [j for j in joints if j.get("type") == "continuous"]
    _check_roots(planar, floating, root, base, source)
    if not continuous and not planar and base == "fixed":
        return urdf_xml
    for joint in continuous:
        _unbounded_revolute(joint)
    if planar:
        _split_planar(robot, planar[0], source)
    elif base != "fixed":
        _add_planar_root(robot, root, source)
    return ET.tostring(robot, encoding="unicode")


def _root_link(robot: ET.Element, source: str) -> str:
    """The URDF's root link: the one link that is no joint's child."""
    children = {child.get("link") for joint in robot.findall("joint") for child in joint.findall("child")}
    roots = [link.get("name") for link in robot.findall("link") if link.get("name") not in children]
    if len(roots) != 1:
        raise BaseError(f"{source}: expected one root link (a link that is no joint's child), found {roots}")
    return str(roots[0])


def _parent(joint: ET.Element) -> str | None:
    parent = joint.find("parent")
    return None if parent is None else parent.get("link")


def _check_roots(
    planar: Sequence[ET.Element], floating: Sequence[ET.Element], root: str, base: str, source: str
) -> None:
    """Refuse what the chart cannot express: a floating joint, a planar joint not at the root, a second
    planar root, or a URDF root that already moves when robot.base: diff_drive adds its own."""
    if floating:
        names = ", ".join(repr(j.get("name")) for j in floating)
        raise BaseError(
            f"{source}: joint {names} is floating (6 dof): a robot here stands on the ground; make it fixed and "
            "set robot.base: planar or diff_drive for a base that moves in the plane"
        )
    inner = [j for j in planar if _parent(j) != root]
    if inner or len(planar) > 1:
        names = ", ".join(repr(j.get("name")) for j in (inner or planar))
        raise BaseError(
            f"{source}: planar joint {names} is not the one joint at the root link {root!r}: only the root may move "
            "in the plane (robot.base: planar)"
        )
    if planar and base == "diff_drive":
        raise BaseError(
            f"robot.base: diff_drive adds the planar root the wheels move, but {source}'s root already floats (planar "
            f"joint {planar[0].get('name')!r}): set robot.base: planar to keep it holonomic, or make that joint fixed"
        )
    axis = planar[0].find("axis") if planar else None
    if axis is not None and [float(v) for v in (axis.get("xyz") or "0 0 1").split()] != [0.0, 0.0, 1.0]:
        raise BaseError(
            f"{source}: planar joint {planar[0].get('name')!r} has axis {axis.get('xyz')}: the plane must be the "
            "joint frame's x-y plane (axis 0 0 1; turn the frame with <origin rpy>)"
        )


def _unbounded_revolute(joint: ET.Element) -> None:
    """A continuous joint as a revolute one about the same axis, its limits pinocchio's "none"."""
    joint.set("type", "revolute")
    limit = joint.find("limit")
    if limit is None:
        limit = ET.SubElement(joint, "limit", effort=NO_LIMIT, velocity=NO_LIMIT)
    limit.set("lower", "-" + NO_LIMIT)
    limit.set("upper", NO_LIMIT)


def _base_joints(parent: str, child: str, origin: ET.Element | None) -> list[ET.Element]:
    """base_x, base_y, base_yaw from ``parent`` to ``child`` (the first at ``origin``), massless links between."""
    elements = []
    links = [parent, "base_x_link", "base_y_link", child]
    for k, (name, kind, axis) in enumerate(
        zip(BASE_JOINTS, ("prismatic", "prismatic", "revolute"), ("1 0 0", "0 1 0", "0 0 1"), strict=True)
    ):
        joint = ET.Element("joint", name=name, type=kind)
        ET.SubElement(joint, "parent", link=links[k])
        ET.SubElement(joint, "child", link=links[k + 1])
        if k == 0 and origin is not None:
            joint.append(origin)
        ET.SubElement(joint, "axis", xyz=axis)
        ET.SubElement(joint, "limit", lower="-" + NO_LIMIT, upper=NO_LIMIT, effort=NO_LIMIT, velocity=NO_LIMIT)
        elements.append(joint)
    return elements


def _check_free(robot: ET.Element, names: Sequence[str], kind: str, source: str) -> None:
    taken = {element.get("name") for element in robot.findall(kind)}
    clash = [name for name in names if name in taken]
    if clash:
        raise BaseError(f"{source}: a {kind} named {clash[0]!r} already exists; the planar base adds one of that name")


def _split_planar(robot: ET.Element, planar: ET.Element, source: str) -> None:
    """The URDF's planar root joint as base_x, base_y, base_yaw at its origin."""
    _check_free(robot, [n for n in BASE_JOINTS if n != planar.get("name")], "joint", source)
    _check_free(robot, ("base_x_link", "base_y_link"), "link", source)
    child = planar.find("child")
    index = list(robot).index(planar)
    robot.remove(planar)
    for name in ("base_x_link", "base_y_link"):
        ET.SubElement(robot, "link", name=name)
    robot[index:index] = _base_joints(
        str(_parent(planar)), str(child.get("link") if child is not None else ""), planar.find("origin")
    )


def _add_planar_root(robot: ET.Element, root: str, source: str) -> None:
    """A new root link ``odom`` and base_x, base_y, base_yaw from it to the URDF's root link."""
    _check_free(robot, BASE_JOINTS, "joint", source)
    _check_free(robot, (ODOM_LINK, "base_x_link", "base_y_link"), "link", source)
    for name in (ODOM_LINK, "base_x_link", "base_y_link"):
        robot.insert(0, ET.Element("link", name=name))
    robot.extend(_base_joints(ODOM_LINK, root, None))


@dataclass(frozen=True)
class Wheels:
    """A differential drive's wheels (diff_drive_controller's names): the joints of each side, their common
    radius [m] and the distance between the two sides' contact lines [m]."""

    left: tuple[str, ...]
    right: tuple[str, ...]
    radius: float
    separation: float

    @property
    def names(self) -> tuple[str, ...]:
        return self.left + self.right


# A differential drive's base joints have no motor; in voltage mode each joint has a motor circuit (a shorted
# one would brake the base), so turning wheels take torque input for now.
TURNING_WHEELS = (
    "robot.base: diff_drive with turning wheels takes input_mode: torque (the base joints have no motor circuit); "
    "or lock both wheels (robot.locked_joints: a braked base), or set robot.base: planar"
)


def passive_padded(motors: MotorParams) -> MotorParams:
    """``motors`` and one more row for the joints without a motor (a differential drive's base): torque input
    gives them no torque (the law's is zero there); its values only keep the parameters' checks."""
    values = {name: np.append(getattr(motors, name), 0.0 if name in _ZERO_FOR_PASSIVE else 1.0) for name in FIELDS}
    return MotorParams(
        **values,
        voltage_limit=motors.voltage_limit,
        torque_limit=np.append(motors.torque_limit, 0.0),
        thermal=motors.thermal,
        ambient_temperature=motors.ambient_temperature,
        temperature_coefficient=motors.temperature_coefficient,
    )


_ZERO_FOR_PASSIVE = ("rotor_inertia", "gear_damping", "transmission_radius")


def wheels_of(robot: Section) -> Wheels | None:
    """robot.base: diff_drive's wheels from the schema's typed ``robot`` values; BaseError names a missing or bad
    one."""
    if robot.base != "diff_drive":
        return None
    for key, names in (("left_wheel_names", robot.left_wheel_names), ("right_wheel_names", robot.right_wheel_names)):
        if not names:
            raise BaseError(f"robot.{key}: robot.base: diff_drive needs the wheel's joint (one per side), got none")
    for key, length in (("wheel_radius", robot.wheel_radius), ("wheel_separation", robot.wheel_separation)):
        if not length > 0.0:
            raise BaseError(f"robot.{key}: robot.base: diff_drive needs it > 0 [m], got {length!r}")
    return Wheels(
        tuple(robot.left_wheel_names),
        tuple(robot.right_wheel_names),
        robot.wheel_radius,
        robot.wheel_separation,
    )


def braked(
    wheels: Wheels, locked: Sequence[str], positions: Sequence[float]
) -> tuple[Wheels | None, list[str], list[float]]:
    """The wheels that roll (None: both locked, a braked base) and the locked joints with their positions: on
    wheels that can neither turn nor slip the base cannot move, so base_x, base_y, base_yaw lock with them (at
    robot.locked_positions if listed, else 0). BaseError for one wheel locked alone."""
    held = [name for name in wheels.names if name in locked]
    if not held:
        return wheels, list(locked), list(positions)
    if len(held) == 1:
        raise BaseError(
            f"robot.locked_joints: {held} locks one wheel of the differential drive: lock both (a braked base) "
            "or neither"
        )
    values = list(positions) or [0.0] * len(locked)
    added = [name for name in BASE_JOINTS if name not in locked]
    return None, [*locked, *added], [*values, *[0.0] * len(added)]


def wheel_problem(wheels: Wheels, urdf: Path, listed: Sequence[str], locked: Sequence[str]) -> str | None:
    """Why ``wheels`` cannot drive the base of the URDF at ``urdf``, or None. ``listed``: robot.joint_names;
    ``locked``: robot.locked_joints."""
    try:
        kinds = urdf_joint_types(urdf.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ET.ParseError):
        return None  # the model's loading names what is wrong with the file
    source = str(urdf)
    for side in ("left", "right"):
        names = getattr(wheels, side)
        if len(names) != 1:
            return (
                f"robot.{side}_wheel_names: {list(names)}: one wheel per side (the rolling rows are one axle's: two "
                "wheels, each rolling without slipping; casters are passive links of the base)"
            )
    for name in wheels.names:
        if name not in kinds:
            return f"robot.left_wheel_names / right_wheel_names: {name!r} is not a joint of {source}"
        if kinds[name] not in ("continuous", "revolute"):
            return (
                f"robot.left_wheel_names / right_wheel_names: {name!r} is a {kinds[name]} joint of {source}; a wheel "
                "turns on a continuous or revolute joint"
            )
        if name not in listed and name not in locked:
            return (
                f"robot.joint_names omits the wheel {name!r}: the wheels are the base's motors, list it (with a value "
                "in every per-joint list), or hold it in robot.locked_joints (a braked base)"
            )
    if wheels.left[0] == wheels.right[0]:
        return f"robot.left_wheel_names and right_wheel_names both name {wheels.left[0]!r}"
    return None


def urdf_joint_types(urdf_xml: str) -> dict[str, str]:
    """Each joint of the URDF text and its type as written (continuous, revolute, prismatic, fixed, ...)."""
    return {str(j.get("name")): str(j.get("type")) for j in ET.fromstring(urdf_xml).findall("joint")}


def axle_problem(model: pin.Model, wheels: Wheels, tolerance: float = 1e-6) -> str | None:
    """Why the URDF's wheels (at the neutral posture) are not the two wheels of one axle ``wheels`` describes:
    spin axes parallel and horizontal, the centres on a common axis, wheel_separation [m] apart, or None."""
    data = model.createData()
    q = pin.neutral(model)
    pin.computeJointJacobians(model, data, q)
    centres, axes = [], []
    for name in wheels.names:
        joint = model.getJointId(name)
        jacobian = pin.getJointJacobian(model, data, joint, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        centres.append(np.array(data.oMi[joint].translation))
        axes.append(np.array(jacobian[3:, model.idx_vs[joint]]))
    offset, names = centres[1] - centres[0], "robot.left_wheel_names / right_wheel_names"
    if abs(axes[0][2]) > tolerance or np.linalg.norm(np.cross(axes[0], axes[1])) > tolerance:
        return f"{names}: the wheels' spin axes {axes[0]} and {axes[1]} are not one horizontal axle"
    if np.linalg.norm(np.cross(offset, axes[0])) > tolerance or abs(offset[2]) > tolerance:
        return f"{names}: the wheels' centres {centres[0]} and {centres[1]} are not on their common axis"
    apart = float(np.linalg.norm(offset))
    if abs(apart - wheels.separation) > tolerance:
        return (
            f"robot.wheel_separation: {wheels.separation!r} m, but the URDF's wheels are {apart:.6g} m apart: set that"
        )
    return None
