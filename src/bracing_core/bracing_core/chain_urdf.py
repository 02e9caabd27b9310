"""URDF of serial chains of solid links: the paper's arm and the further scenarios' robots.

``serial_chain_urdf`` writes any serial chain of 1-dof joints. Every joint has a name, a
type (``revolute`` | ``prismatic``), a unit axis in its parent link's frame, an origin on
the parent's local +z axis (by default at the parent link's tip), URDF position / effort /
velocity limits and a viscous damping (``<dynamics damping>``: N m s/rad, or N s/m for a
prismatic joint). Every link has a mass, a length along its local +z axis and a radius
(solid cylinder, centre of mass mid-link) or a box size / explicit principal inertia (a
cart); its ``<visual>`` and ``<collision>`` are the same shape (the cylinder, the box, or a ball for a
link of no length). Joint origins carry no rotation, so at q = 0 every link frame is parallel to the
world frame. Fixed frames can be put at the tip of any link (the paper's ``elbow`` at the
tip of link 2, ``hand`` at the tip of link 4).

``chain_urdf`` is the planar special case the paper uses (joints about the world x axis,
links along +z at q = 0, joint ``k+1`` at the tip of link ``k``).

``python -m bracing_core.chain_urdf NAME`` prints the URDF of a shipped scenario
(paper_4link, hyper_7link, mobile_8joint, writing_desk; wall_7link uses hyper_7link's
robot); ``config/NAME.urdf`` is exactly that output.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

_TWO_PI = 6.283185307179586
# The paper's arm states no joint limits. A URDF revolute joint needs a <limit>, and the simulator
# stops at one (RobotModel: URDF limits are never ignored), so "none" is a range no run reaches.
UNLIMITED = 100.0  # [rad]


@dataclass(frozen=True)
class JointSpec:
    """One 1-dof joint: it moves the link of the same index in ``serial_chain_urdf``."""

    name: str
    type: str = "revolute"  # revolute | prismatic
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)  # unit vector, parent link frame
    lower: float = -_TWO_PI  # [rad] or [m]
    upper: float = _TWO_PI  # [rad] or [m]
    effort: float = 1000.0  # [N m] or [N]
    velocity: float = 100.0  # [rad/s] or [m/s]
    damping: float = 0.0  # link-side viscous friction D [N m s/rad] or [N s/m]
    friction: float = 0.0  # URDF <dynamics friction> (not used by the model)
    offset: float | None = None  # origin on the parent's local z [m]; None = the parent link's length


@dataclass(frozen=True)
class LinkSpec:
    """One rigid link along its local +z axis from its joint; centre of mass at length / 2."""

    name: str
    mass: float  # [kg]
    length: float  # [m], along local +z; the next joint and tip frames sit at the tip
    radius: float = 0.0  # [m], solid cylinder (used unless ``box`` or ``inertia`` says otherwise)
    box: tuple[float, float, float] | None = None  # (x, y, z) size [m] of a solid box (visual and inertia)
    inertia: tuple[float, float, float] | None = None  # principal (ixx, iyy, izz) about the COM [kg m^2]


def _cylinder_inertia(mass: float, radius: float, length: float) -> tuple[float, float, float]:
    """Principal inertias (ixx, iyy, izz) [kg m^2] of a solid cylinder about its centre, axis z."""
    transverse = mass * (3.0 * radius**2 + length**2) / 12.0
    return transverse, transverse, 0.5 * mass * radius**2


def _box_inertia(mass: float, size: tuple[float, float, float]) -> tuple[float, float, float]:
    """Principal inertias (ixx, iyy, izz) [kg m^2] of a solid box of size (x, y, z) about its centre."""
    x, y, z = size
    return mass * (y**2 + z**2) / 12.0, mass * (x**2 + z**2) / 12.0, mass * (x**2 + y**2) / 12.0


def _axis_text(axis: Sequence[float]) -> str:
    """'1 0 0' for the unit axes (as the paper's URDF has it), repr otherwise."""
    if len(axis) != 3:
        raise ValueError(f"axis {tuple(axis)} needs three components")
    norm = math.sqrt(sum(float(a) ** 2 for a in axis))
    if abs(norm - 1.0) > 1e-9:
        raise ValueError(f"axis {tuple(axis)} is not a unit vector (norm {norm})")
    return " ".join(str(int(a)) if float(a).is_integer() else repr(float(a)) for a in axis)


def _link_inertia(link: LinkSpec) -> tuple[float, float, float]:
    """Principal inertias about the COM: the explicit ones, else the box's, else the cylinder's."""
    if link.inertia is not None:
        return link.inertia
    if link.box is not None:
        return _box_inertia(link.mass, link.box)
    return _cylinder_inertia(link.mass, link.radius, link.length)


def _link_geometry(link: LinkSpec) -> str:
    """The visual's and collision's shape: the box, else a cylinder of the link's length, else a ball."""
    if link.box is not None:
        return '<box size="{!r} {!r} {!r}"/>'.format(*link.box)
    if link.length > 0.0:
        return f'<cylinder radius="{link.radius!r}" length="{link.length!r}"/>'
    return f'<sphere radius="{link.radius!r}"/>'  # a joint housing of no length: a ball


def _check_joint(joint: JointSpec) -> None:
    if joint.type not in ("revolute", "prismatic"):
        raise ValueError(f"joint {joint.name!r}: type {joint.type!r} is not revolute or prismatic")
    if not joint.lower < joint.upper:
        raise ValueError(f"joint {joint.name!r}: lower limit {joint.lower} not below upper {joint.upper}")


def _moving_link_lines(joint: JointSpec, link: LinkSpec, parent: str, offset: float) -> list[str]:
    """The URDF of ``joint`` (at ``offset`` on ``parent``'s z axis) and of the ``link`` it moves."""
    _check_joint(joint)
    ixx, iyy, izz = _link_inertia(link)
    geometry = _link_geometry(link)
    centre = link.length / 2.0
    return [
        f'  <joint name="{joint.name}" type="{joint.type}">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{link.name}"/>',
        f'    <origin xyz="0 0 {offset!r}" rpy="0 0 0"/>',
        f'    <axis xyz="{_axis_text(joint.axis)}"/>',
        f'    <limit lower="{joint.lower!r}" upper="{joint.upper!r}" effort="{joint.effort!r}"'
        f' velocity="{joint.velocity!r}"/>',
        f'    <dynamics damping="{joint.damping!r}" friction="{joint.friction!r}"/>',
        "  </joint>",
        f'  <link name="{link.name}">',
        "    <inertial>",
        f'      <origin xyz="0 0 {centre!r}" rpy="0 0 0"/>',
        f'      <mass value="{link.mass!r}"/>',
        f'      <inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" izz="{izz!r}"/>',
        "    </inertial>",
        "    <visual>",
        f'      <origin xyz="0 0 {centre!r}" rpy="0 0 0"/>',
        f"      <geometry>{geometry}</geometry>",
        "    </visual>",
        # The collision shape is the drawn one: what bracing-view shows is what robot.collision_geometry
        # measures and MuJoCo collides (no inertia of its own: <inertial> alone sets the dynamics).
        "    <collision>",
        f'      <origin xyz="0 0 {centre!r}" rpy="0 0 0"/>',
        f"      <geometry>{geometry}</geometry>",
        "    </collision>",
        "  </link>",
    ]


def _tip_frame_lines(frame: str, where: int | str, links: Sequence[LinkSpec]) -> list[str]:
    """A fixed frame at the tip of the link ``where`` (1-based index or link name)."""
    names = [link.name for link in links]
    if isinstance(where, str):
        if where not in names:
            raise ValueError(f"frame {frame!r}: no link named {where!r}")
        index = names.index(where)
    else:
        if not 1 <= where <= len(links):
            raise ValueError(f"frame {frame!r}: link index {where} not in 1..{len(links)}")
        index = where - 1
    return [
        f'  <joint name="{frame}_joint" type="fixed">',
        f'    <parent link="{names[index]}"/>',
        f'    <child link="{frame}"/>',
        f'    <origin xyz="0 0 {links[index].length!r}" rpy="0 0 0"/>',
        "  </joint>",
        f'  <link name="{frame}"/>',
    ]


def serial_chain_urdf(
    name: str,
    joints: Sequence[JointSpec],
    links: Sequence[LinkSpec],
    tip_frames: Mapping[str, int | str] | None = None,
    description: str | None = None,
) -> str:
    """URDF text for a serial chain: ``joints[k]`` moves ``links[k]``; ``links[k-1]`` is its parent
    (``base_link``, fixed to the world, for k = 0). ``tip_frames`` maps a frame name to the link
    (1-based index or link name) at whose tip the frame sits."""
    n = len(joints)
    if n == 0 or len(links) != n:
        raise ValueError("one link per joint, at least one joint")
    names = [link.name for link in links]
    if len(set(names)) != n or "base_link" in names:
        raise ValueError(f"link names must be distinct and not base_link: {names}")
    out = [
        '<?xml version="1.0"?>',
        f"<!-- generated by bracing_core.chain_urdf: {description or f'{n}-joint serial chain'} -->",
        f'<robot name="{name}">',
        '  <link name="base_link"/>',
    ]
    parent, parent_length = "base_link", 0.0
    for joint, link in zip(joints, links, strict=True):
        offset = parent_length if joint.offset is None else joint.offset
        out += _moving_link_lines(joint, link, parent, offset)
        parent, parent_length = link.name, link.length
    for frame, where in (tip_frames or {}).items():
        out += _tip_frame_lines(frame, where, links)
    out.append("</robot>")
    return "\n".join(out) + "\n"


def chain_urdf(
    name: str,
    masses: Sequence[float],
    lengths: Sequence[float],
    radii: Sequence[float],
    damping: Sequence[float],
    tip_frames: Mapping[str, int] | None = None,
    effort_limit: float = 1000.0,
    position_limit: float = UNLIMITED,
) -> str:
    """URDF text for the planar chain (joints ``joint1``.. about x with limits +-``position_limit``,
    links ``link1``..). ``tip_frames`` maps a frame name to a 1-based link index."""
    n = len(masses)
    if not (len(lengths) == len(radii) == len(damping) == n) or n == 0:
        raise ValueError("masses, lengths, radii and damping need one entry per link")
    joints = [
        JointSpec(f"joint{k + 1}", damping=damping[k], effort=effort_limit, lower=-position_limit, upper=position_limit)
        for k in range(n)
    ]
    links = [LinkSpec(f"link{k + 1}", masses[k], lengths[k], radii[k]) for k in range(n)]
    return serial_chain_urdf(name, joints, links, tip_frames, description=f"{n}-link planar chain")


def paper_4link_urdf() -> str:
    """The paper's Table 1 arm: elbow = tip of link 2, hand = tip of link 4."""
    return chain_urdf(
        "paper_4link",
        masses=(1.0, 1.0, 0.5, 1.0),
        lengths=(0.5, 0.5, 0.5, 0.5),
        radii=(0.03, 0.03, 0.01, 0.03),
        damping=(2.0, 2.0, 2.0, 2.0),
        tip_frames={"elbow": 2, "hand": 4},
    )


# --- The 7-link arm of hyper_7link / wall_7link / mobile_8joint -------------------------------
# Seven links of 0.3 m: a 2.1 m reach, close to the paper's 2.0 m, with two "elbows" (tips of
# links 2 and 4) that can rest on the floor or a wall while links 5-7 still reach 0.9 m.
# Masses fall off towards the tip (each link carries the motors of the joints after it): from
# 0.9 kg (3 kg/m) at the base down to 0.3 kg (1 kg/m) at the hand, around the paper's 2 kg/m
# (1 kg per 0.5 m) on average, 4.2 kg in all. Radii shrink with the mass (3.5 cm to 2 cm, the paper uses
# 1-3 cm). D = 2.0 N m s/rad per joint as in Table 1.
_ARM7_LENGTH = 0.3
_ARM7_MASSES = (0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3)
_ARM7_RADII = (0.035, 0.03, 0.03, 0.025, 0.025, 0.02, 0.02)
_ARM7_DAMPING = 2.0
# Limits +-pi: a planar joint never needs more than half a turn either way; the start postures
# and the whole hand circle of hyper_7link / wall_7link / mobile_8joint keep every joint at least
# 0.37 rad inside (joint5, folded back at elbow2, comes closest: up to 2.77 rad).
# Velocity 6 rad/s: a small geared DC motor (the hand circle needs well under 1 rad/s).
_ARM7_LIMIT = math.pi
_ARM7_VELOCITY = 6.0
_ARM7_FRAMES: dict[str, int] = {
    "elbow1": 2,  # braced: floor (hyper_7link, mobile_8joint and wall_7link)
    "elbow2": 4,  # braced: floor (hyper_7link, mobile_8joint) or wall (wall_7link)
    "hand": 7,  # the hand task
    "link1_tip": 1,  # the other tips: collision frames
    "link3_tip": 3,
    "link5_tip": 5,
    "link6_tip": 6,
}


def _holding_torque(masses: Sequence[float], lengths: Sequence[float], start: int) -> float:
    """Gravity torque [N m] about joint ``start`` (0-based) of links start.. held out horizontally."""
    torque, reach = 0.0, 0.0
    for m, length in zip(masses[start:], lengths[start:], strict=True):
        torque += m * 9.81 * (reach + length / 2.0)
        reach += length
    return torque


def _effort(masses: Sequence[float], lengths: Sequence[float], start: int) -> float:
    """Effort limit: twice the torque to hold the rest of the arm out horizontally (unbraced),
    rounded up to 5 N m: room for the contact force and the tasks on top of gravity."""
    return 5.0 * math.ceil(2.0 * _holding_torque(masses, lengths, start) / 5.0)


def _arm7() -> tuple[list[JointSpec], list[LinkSpec]]:
    lengths = (_ARM7_LENGTH,) * 7
    joints = [
        JointSpec(
            f"joint{k + 1}",
            lower=-_ARM7_LIMIT,
            upper=_ARM7_LIMIT,
            effort=_effort(_ARM7_MASSES, lengths, k),
            velocity=_ARM7_VELOCITY,
            damping=_ARM7_DAMPING,
        )
        for k in range(7)
    ]
    links = [LinkSpec(f"link{k + 1}", _ARM7_MASSES[k], lengths[k], _ARM7_RADII[k]) for k in range(7)]
    return joints, links


def hyper_7link_urdf() -> str:
    """Planar 7-link arm (joints about x, links along +z at q = 0), base joint at the origin."""
    joints, links = _arm7()
    return serial_chain_urdf("hyper_7link", joints, links, _ARM7_FRAMES, description="7-link planar chain")


# --- mobile_8joint: the same arm on a cart ------------------------------------------------------
# The cart rolls along the world y axis (the arm's plane of motion) on a prismatic joint that a
# DC motor drives through a wheel (motors.transmission_radius). It is a low, wide box:
# 0.30 m (x) x 0.40 m (y) x 0.12 m (z) including the wheels, 5 kg (a small aluminium chassis with
# battery and drive motor): heavier than the arm's first link, light enough that the arm's
# contact forces can push it around. The arm's joint1 sits on the cart top, 0.12 m above the floor.
# Limits +-0.5 m: a short rail-like workspace either side of the start (base at 0).
# Damping 5 N s/m: rolling resistance c_rr m g ~ 0.015 x 9.2 kg x 9.81 ~ 1.4 N, linearised
# at ~0.25 m/s, plus bearing drag. Effort 70 N: the traction limit of rubber wheels (mu ~0.8)
# under the 9.2 kg of cart and arm; more force would only spin the wheels.
_CART_SIZE = (0.30, 0.40, 0.12)
_CART_MASS = 5.0
_CART_TRAVEL = 0.5
_CART_DAMPING = 5.0
_CART_EFFORT = 70.0
_CART_VELOCITY = 1.0


def mobile_8joint_urdf() -> str:
    """``base_joint`` (prismatic along world y) carrying the cart, then the 7-link arm."""
    joints, links = _arm7()
    base = JointSpec(
        "base_joint",
        type="prismatic",
        axis=(0.0, 1.0, 0.0),
        lower=-_CART_TRAVEL,
        upper=_CART_TRAVEL,
        effort=_CART_EFFORT,
        velocity=_CART_VELOCITY,
        damping=_CART_DAMPING,
    )
    cart = LinkSpec("cart", _CART_MASS, _CART_SIZE[2], box=_CART_SIZE)
    return serial_chain_urdf(
        "mobile_8joint",
        [base, *joints],
        [cart, *links],
        {frame: links[index - 1].name for frame, index in _ARM7_FRAMES.items()},
        description="cart on a prismatic joint along y carrying a 7-link planar chain",
    )


# --- writing_desk: a spatial, human-like arm ---------------------------------------------------
# The desk top is the plane z = 0; the shoulder (joints 1-3 intersect there) is 0.20 m above it,
# the height of a seated writer's shoulder leaning over the desk, with the torso (base_link) at
# the world origin and the desk in front along +y. At q = 0 the arm points straight up (+z).
# Seven revolute joints as a human arm: shoulder yaw (z), shoulder pitch (x), upper-arm roll
# (z, along the upper arm), elbow pitch (x), forearm roll (z, along the forearm), wrist pitch (x)
# and wrist yaw (y). Upper arm 0.30 m, forearm 0.27 m, hand + pen 0.15 m (pen tip = hand tip).
# Masses of a light robot arm of that size (1.0 / 0.6 / 0.2 kg); the three joint housings of
# no length (shoulder yaw, shoulder pitch, wrist pitch) get a small mass (every moving link needs
# one) and a radius, so that their joints keep some inertia of their own.
# Damping falls from 1.0 N m s/rad at the shoulder to 0.2 at the wrist: the paper's D = 2 scaled
# to these lighter links.
# Limits: human ranges in this chain's sign conventions (q = 0 points the arm straight up; the
# arm reaches forward, +y, for a negative shoulder pitch, and, with the upper arm unrolled, the
# elbow flexes and the hand lifts for a positive elbow pitch and bends down to the desk for a
# negative wrist pitch). The writing_desk start posture and every point of its pen figure keep each
# joint at least 0.28 rad inside these limits. Efforts: at least 3x the torque that holds the rest
# of the arm out horizontally (6.4 N m at the shoulder, 1.7 N m at the elbow, 0.15 N m at the wrist).
_DESK_SHOULDER_HEIGHT = 0.20
_DESK_VELOCITY = 6.0
_DESK_JOINTS: tuple[tuple[str, tuple[float, float, float], float, float, float, float], ...] = (
    # name, axis, lower, upper [rad], effort [N m], damping [N m s/rad]
    ("shoulder_yaw", (0.0, 0.0, 1.0), -1.6, 1.6, 20.0, 1.0),  # +-90 deg across the body / outwards
    ("shoulder_pitch", (1.0, 0.0, 0.0), -3.1, 0.3, 20.0, 1.0),  # hanging (-pi) to overhead (0) and 17 deg on
    ("upper_arm_roll", (0.0, 0.0, 1.0), -1.6, 1.6, 10.0, 1.0),  # +-90 deg rotation of the upper arm
    ("elbow_pitch", (1.0, 0.0, 0.0), 0.0, 2.6, 10.0, 0.8),  # 0 (straight) to 150 deg flexion
    ("forearm_roll", (0.0, 0.0, 1.0), -1.6, 1.6, 5.0, 0.3),  # pronation / supination +-90 deg
    ("wrist_pitch", (1.0, 0.0, 0.0), -1.4, 1.0, 5.0, 0.2),  # flexion 80 deg / extension 57 deg
    ("wrist_yaw", (0.0, 1.0, 0.0), -0.5, 0.5, 5.0, 0.2),  # radial / ulnar deviation +-29 deg
)
_DESK_LINKS = (
    # name, mass [kg], length [m], radius [m]
    ("shoulder_yaw_link", 0.3, 0.0, 0.05),
    ("shoulder_pitch_link", 0.3, 0.0, 0.05),
    ("upper_arm", 1.0, 0.30, 0.04),
    ("elbow_link", 0.2, 0.0, 0.04),
    ("forearm", 0.6, 0.27, 0.035),
    ("wrist_link", 0.1, 0.0, 0.03),
    ("hand_link", 0.2, 0.15, 0.02),
)
_DESK_FRAMES: dict[str, str] = {
    "elbow": "upper_arm",  # braced on the desk
    "wrist": "forearm",  # collision frame
    "pen": "hand_link",  # the pen tip: on the desk, writing
}


def writing_desk_urdf() -> str:
    """Spatial 7-joint arm whose shoulder is 0.2 m above the desk top z = 0."""
    joints = [
        JointSpec(
            name,
            axis=axis,
            lower=lower,
            upper=upper,
            effort=effort,
            velocity=_DESK_VELOCITY,
            damping=damping,
            offset=_DESK_SHOULDER_HEIGHT if k == 0 else None,
        )
        for k, (name, axis, lower, upper, effort, damping) in enumerate(_DESK_JOINTS)
    ]
    links = [LinkSpec(name, mass, length, radius) for name, mass, length, radius in _DESK_LINKS]
    return serial_chain_urdf(
        "writing_desk", joints, links, _DESK_FRAMES, description="7-joint spatial arm over a desk top z = 0"
    )


SCENARIOS: dict[str, Callable[[], str]] = {
    "paper_4link": paper_4link_urdf,
    "hyper_7link": hyper_7link_urdf,
    "wall_7link": hyper_7link_urdf,  # the same robot as hyper_7link (config/hyper_7link.urdf)
    "mobile_8joint": mobile_8joint_urdf,
    "writing_desk": writing_desk_urdf,
}


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m bracing_core.chain_urdf",
        description="Print the URDF of a shipped scenario (config/NAME.urdf is this output).",
    )
    parser.add_argument("name", nargs="?", default="paper_4link", choices=sorted(SCENARIOS))
    args = parser.parse_args(argv)
    print(SCENARIOS[args.name](), end="")


if __name__ == "__main__":  # regenerate config/NAME.urdf: python -m bracing_core.chain_urdf NAME > config/NAME.urdf
    main()
