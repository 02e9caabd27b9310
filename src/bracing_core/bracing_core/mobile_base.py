"""A mobile base's ROS face, without ROS: odometry from the base's state, cmd_vel taken as
ros2_controllers' diff_drive_controller takes it, and the base following it.

The planar base's three coordinates are the joints ``base_x``, ``base_y`` (world position of the root
link [m]) and ``base_yaw`` (its heading [rad], unwrapped), wherever joints are listed (SPEC section 8).
Conventions, as diff_drive_controller (ros2_controllers, ``diff_drive_controller.cpp``) has them:

- ``odom`` (nav_msgs/Odometry): header.frame_id ``odom``, child_frame_id the root link; the pose in the
  plane (z = 0, a rotation about z); the twist in the child frame (linear.x forward, linear.y to the
  left, angular.z), as nav_msgs documents it; covariances zero (the simulator's pose is exact);
- ``cmd_vel`` (geometry_msgs/TwistStamped): a zero stamp means now; a message older than
  ``cmd_vel_timeout`` when it comes is ignored; one whose used components are not finite is ignored
  (the previous command stays); a command older than ``cmd_vel_timeout`` brakes (zero velocity);
  ``cmd_vel_timeout`` 0 turns both off;
- the wheels' inverse kinematics: w_left = (v - omega s / 2) / r, w_right = (v + omega s / 2) / r.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from bracing_core.base import BASE_JOINTS, Wheels
from bracing_core.types import Vector

ODOM_FRAME = "odom"
"""The odometry frame (diff_drive_controller's ``odom_frame_id`` default)."""
ODOM_TOPIC = "odom"
CMD_VEL_TOPIC = "cmd_vel"
ARM_AUTHORITY = 1e-3
"""``keep_contact_force``: the smallest singular value of the arm's B = J_c Mc^-1, relative to its largest, used."""


def root_link(model: Any) -> str:
    """The link the base carries (odom's child frame): the body right after base_yaw (a joint, or a fixed frame
    once the base is locked), else the first body of the model's first joint."""
    if model.existFrame("base_yaw"):
        after = model.getFrameId("base_yaw")
        for frame in model.frames:
            if frame.previousFrame == after and frame.type == pin.FrameType.BODY:
                return str(frame.name)
    for frame in model.frames:
        if frame.parentJoint == 1 and frame.type == pin.FrameType.BODY:
            return str(frame.name)
    raise ValueError("no link carried by the base")


def base_indices(joint_names: Sequence[str]) -> tuple[int, int, int] | None:
    """Where base_x, base_y and base_yaw are in ``joint_names`` (None: the robot has no planar base there)."""
    if not all(name in joint_names for name in BASE_JOINTS):
        return None
    names = list(joint_names)
    x, y, yaw = (names.index(name) for name in BASE_JOINTS)
    return x, y, yaw


@dataclass(frozen=True)
class BaseOdometry:
    """The root link's pose in the plane (world = odom) and its twist in its own frame."""

    x: float  # [m]
    y: float  # [m]
    yaw: float  # [rad], unwrapped
    forward: float  # [m/s] along the root link's x (Odometry twist.linear.x)
    left: float  # [m/s] along its y (twist.linear.y: 0 for a base that rolls without slipping)
    yaw_rate: float  # [rad/s] (twist.angular.z)

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """The heading as a quaternion (x, y, z, w): a rotation about z."""
        return 0.0, 0.0, math.sin(0.5 * self.yaw), math.cos(0.5 * self.yaw)


def odometry(position: Vector, velocity: Vector, indices: tuple[int, int, int]) -> BaseOdometry:
    """The odometry of a state: base_x, base_y, base_yaw positions and their velocities (world axes) at
    ``indices``; the twist turned into the root link's frame."""
    ix, iy, iyaw = indices
    yaw = float(position[iyaw])
    dx, dy = float(velocity[ix]), float(velocity[iy])
    c, s = math.cos(yaw), math.sin(yaw)
    return BaseOdometry(
        float(position[ix]), float(position[iy]), yaw, c * dx + s * dy, -s * dx + c * dy, float(velocity[iyaw])
    )


def braked_pose(locked_joints: Sequence[str], locked_positions: Sequence[float]) -> BaseOdometry | None:
    """The odometry of a base held in place (base_x, base_y, base_yaw all locked: a differential drive's wheels
    held) at its locked positions, at rest; None if its joints are not all locked."""
    held = dict(zip(locked_joints, list(locked_positions) or [0.0] * len(locked_joints), strict=True))
    if not all(name in held for name in BASE_JOINTS):
        return None
    x, y, yaw = (float(held[name]) for name in BASE_JOINTS)
    return BaseOdometry(x, y, yaw, 0.0, 0.0, 0.0)


def wheel_velocities(forward: float, yaw_rate: float, radius: float, separation: float) -> tuple[float, float]:
    """(left, right) wheel speeds [rad/s] for a forward speed [m/s] and a yaw rate [rad/s], as
    diff_drive_controller turns cmd_vel into wheel commands (``radius``, ``separation`` [m])."""
    half = 0.5 * yaw_rate * separation
    return (forward - half) / radius, (forward + half) / radius


@dataclass(frozen=True)
class BaseTwist:
    """A commanded base velocity in the root link's frame."""

    forward: float = 0.0  # [m/s] linear.x
    left: float = 0.0  # [m/s] linear.y (a holonomic base only)
    yaw_rate: float = 0.0  # [rad/s] angular.z


class CmdVelRefused(ValueError):
    """A cmd_vel the base does not take; ``kind`` (a word) keys its rate limit."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


class CmdVelGate:
    """The latest cmd_vel, kept as diff_drive_controller keeps it (see the module docstring).

    ``timeout_s``: cmd_vel_timeout [s] (0: off); ``holonomic``: linear.y is used (a planar base), else
    ignored as diff_drive_controller ignores it. Times are the node's clock [ns] (the controller's: the
    sim time of the state it answers).
    """

    def __init__(self, timeout_s: float, holonomic: bool) -> None:
        self.timeout_ns = round(timeout_s * 1e9)
        self.holonomic = holonomic
        self.latest: BaseTwist | None = None
        self.latest_ns = 0
        self.braking = False  # the last command asked for was stale: zero

    def offer(self, stamp_ns: int, linear: Sequence[float], angular: Sequence[float], now_ns: int) -> BaseTwist:
        """Take a TwistStamped (its stamp, linear and angular [m/s, rad/s]) at ``now_ns``; what the base will
        follow, or CmdVelRefused saying why not (then the command before it stays)."""
        used = [linear[0], angular[2]] + ([linear[1]] if self.holonomic else [])
        if not all(math.isfinite(v) for v in used):
            names = "linear.x, linear.y, angular.z" if self.holonomic else "linear.x, angular.z"
            raise CmdVelRefused("non-finite", f"{names} must be finite, got {[float(v) for v in used]}")
        stamp_ns = now_ns if stamp_ns == 0 else stamp_ns
        age_ns = now_ns - stamp_ns
        if self.timeout_ns > 0 and age_ns >= self.timeout_ns:
            raise CmdVelRefused(
                "stale",
                f"stamp {stamp_ns * 1e-9:.6f} s is {age_ns * 1e-9:.6f} s old, past cmd_vel_timeout "
                f"{self.timeout_ns * 1e-9:g} s (stamp it with the node's clock: sim time, or zero for now)",
            )
        twist = BaseTwist(float(linear[0]), float(linear[1]) if self.holonomic else 0.0, float(angular[2]))
        self.latest, self.latest_ns = twist, stamp_ns
        return twist

    def command(self, now_ns: int) -> BaseTwist:
        """The velocity to follow at ``now_ns``: the latest cmd_vel, or zero before any and once it is older
        than the timeout (the base brakes); ``braking`` says whether it timed out."""
        if self.latest is None:
            return BaseTwist()
        self.braking = self.timeout_ns > 0 and now_ns - self.latest_ns > self.timeout_ns
        return BaseTwist() if self.braking else self.latest


def rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class BaseFrame:
    """Targets given at the start in the world, carried with the moving base: a point p (velocity v) of the
    start becomes R(yaw - yaw0) (p - p0) + p_b, its velocity R v + v_b + omega z x R (p - p0), (p_b, yaw)
    the base's pose now, p0, yaw0 at the start."""

    def __init__(self, start: BaseOdometry) -> None:
        self.origin = np.array([start.x, start.y, 0.0])
        self.yaw0 = start.yaw

    def carry(
        self, base: BaseOdometry, world_velocity: Vector, point: Vector, velocity: Vector
    ) -> tuple[Vector, Vector]:
        """(position, velocity) of a start-time target ``point`` moving ``velocity`` [m, m/s] with the base
        at ``base`` moving ``world_velocity`` (dx, dy [m/s], dyaw [rad/s])."""
        rotation = rotation_z(base.yaw - self.yaw0)
        offset = rotation @ (np.asarray(point, dtype=float) - self.origin)
        position = offset + np.array([base.x, base.y, 0.0])
        spin = np.array([0.0, 0.0, float(world_velocity[2])])
        carried = rotation @ np.asarray(velocity, dtype=float) + np.cross(spin, offset)
        carried[:2] += np.asarray(world_velocity[:2], dtype=float)
        return position, carried


def world_twist(twist: BaseTwist, yaw: float) -> Vector:
    """A twist in the root link's frame as the base joints' velocities (dx, dy [m/s], dyaw [rad/s])."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * twist.forward - s * twist.left, s * twist.forward + c * twist.left, twist.yaw_rate])


class BaseDrive:
    """The base following cmd_vel (``base_command: cmd_vel``): on the base's actuators (base_x, base_y,
    base_yaw; or the wheels, each side at the speed diff_drive_controller's inverse kinematics gives) a
    velocity loop tau = kd (v_cmd - v) is added to the law's command (the law keeps its whole-body torques:
    without them its tasks, planned with the base's share, run away); the tasks' paths, given in the world at
    the start, are carried with the base (``BaseFrame``), so the hand is tracked relative to the moving base."""

    def __init__(
        self, joint_names: Sequence[str], timeout_s: float, kd: float, wheels: Wheels | None = None, ki: float = 0.0
    ) -> None:
        """``joint_names``: the law's (model order); ``wheels``: a differential drive's (None: the base's joints are
        its actuators); ``ki``: the loop's integral gain (0: none), on the commanded velocity's integral."""
        indices = base_indices(joint_names)
        if indices is None:
            raise ValueError(f"no planar base: {list(BASE_JOINTS)} are not all among {list(joint_names)}")
        self.indices, self.kd, self.wheels = indices, kd, wheels
        names = list(joint_names)
        self.sides = (
            None if wheels is None else ([names.index(j) for j in wheels.left], [names.index(j) for j in wheels.right])
        )
        self.gate = CmdVelGate(timeout_s, holonomic=wheels is None)
        self.frame: BaseFrame | None = None  # set at the first state
        self.ki = ki
        self.reference: Vector | None = None  # the actuators' commanded positions (the velocity's integral)
        self.reference_ns = 0

    @property
    def actuators(self) -> list[int]:
        """The joints whose command the velocity loop sets."""
        if self.sides is None:
            return list(self.indices)
        return [*self.sides[0], *self.sides[1]]

    def targets(self, q: Vector, dq: Vector, paths: Sequence[tuple[Vector, Vector]]) -> list[tuple[Vector, Vector]]:
        """The tasks' references now: each ``paths`` sample (position, velocity at t, world at the start)
        carried with the base at (q, dq)."""
        base = odometry(q, dq, self.indices)
        if self.frame is None:
            self.frame = BaseFrame(base)
        moving = np.array([dq[i] for i in self.indices], dtype=float)
        return [self.frame.carry(base, moving, point, velocity) for point, velocity in paths]

    def torques(self, now_ns: int, q: Vector, dq: Vector) -> Vector:
        """tau [N or N m] of the velocity loop on each of ``actuators`` at the node's time ``now_ns``:
        kd (v_cmd - v) + ki (integral of v_cmd - q)."""
        twist = self.gate.command(now_ns)
        if self.wheels is None:
            wanted = world_twist(twist, float(q[self.indices[2]]))
        else:
            w = self.wheels
            left, right = wheel_velocities(twist.forward, twist.yaw_rate, w.radius, w.separation)
            wanted = np.array([left] * len(w.left) + [right] * len(w.right))
        joints = self.actuators
        position = np.asarray([q[i] for i in joints], dtype=float)
        if self.reference is None:
            self.reference = position
        else:  # the commanded velocity integrated: with ki > 0 the base holds where cmd_vel puts it, no creep
            self.reference = self.reference + wanted * ((now_ns - self.reference_ns) * 1e-9)
        self.reference_ns = now_ns
        velocity = np.asarray([dq[i] for i in joints], dtype=float)
        return self.kd * (wanted - velocity) + self.ki * (self.reference - position)


def keep_contact_force(b: Vector, torque: Vector, base: Sequence[int], base_torque: Vector) -> Vector:
    """``torque`` (the law's, eq. 38) with ``base_torque`` on the joints ``base`` (the law's own plus the base's
    velocity loop), and the other joints' torques changed by the least that keeps B tau as the law set it:
    delta_arm = -B_arm^+ B_base delta_base, B = J_c Mc^-1 (p x n, eq. 36; on a differential drive the rolling
    system's, J_c T (T^T Mc T)^-1, its base columns zero: ``StateAnswerer.contact_map``). Eq. 40
    (A f_n = B tau - a) then gives the normal forces the law chose (f_nd with torque input): the base's loop
    accelerating the robot does not lean on the braces."""
    out = np.array(torque, dtype=float)
    b = np.asarray(b, dtype=float)
    base = list(base)
    others = [j for j in range(out.size) if j not in base]
    delta = np.asarray(base_torque, dtype=float) - out[base]
    out[base] = base_torque
    if b.shape[0] and others:
        # a brace the arm can hardly push along its normal (a singular value of B_arm under ARM_AUTHORITY of
        # the largest) is left as it is: taking the base's push up there would take huge torques
        out[others] -= np.linalg.pinv(b[:, others], rcond=ARM_AUTHORITY) @ (b[:, base] @ delta)
    return out
