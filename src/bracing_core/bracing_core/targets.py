"""Targets while running, no ROS: a new hand or brace target reached without a kick.

The controller's tasks follow their configured paths (the law's ``Path``, in the engine) until a
target arrives over ROS (``hand_target``, ``hand_path``, ``brace_target/<contact>``). From then on the
task's desired position and velocity come from a :class:`Reference` that starts where the path was at
that instant (position and velocity: no jump) and moves toward the goal with its speed and its
acceleration bounded (``targets.max_velocity`` / ``targets.max_acceleration``). The reference is fed to
the law each update (``engine.Law.set_reference``): the law itself is unchanged, and rollouts, which
have no topics and so no targets, run the configured paths exactly as before.

What is refused (``TargetError``, with its ``kind``): another frame than world, a coordinate not finite,
a point out of the frame's reach, and for a path: more poses than ``max_message_elements`` or a frame
name longer than ``max_name_length`` (checked before any per-pose work), stamps out of order, a path
entirely in the past (its last pose before now), or one that ends more than ``targets.max_horizon``
after now (a wall-clock stamp sent to a sim-time controller ends ~1.8e9 s ahead). A goal equal to the
task's current one is no change (``set`` says so: the node logs and echoes changes only).

``hand_pose_target`` (``TaskTargets.pose``) moves the hand's reference as ``hand_target`` does and turns
the orientation task's R_d toward its orientation (:class:`OrientationReference`, fed to the law by
``engine.Law.set_orientation_reference``), starting at rest from the R_d the law held, its angular velocity
and acceleration bounded (``targets.max_angular_velocity`` / ``.max_angular_acceleration``). Refused besides:
a quaternion not finite, zero or far from unit norm (a near-unit one is normalised), and any pose when no
orientation task is configured.

Why here and not in the engine: a target exists only where a ROS message brings it, the generator is
a few vector operations per update (no model), and the engine keeps one small hook instead of a
second kind of path whose timing depends on when messages come.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from bracing_core.checks import Reach
from bracing_core.message_limits import shorten
from bracing_core.types import HAND_TASK, TaskIndex, Vector


class TargetError(ValueError):
    """A target that is refused; ``kind`` names the check it failed (``KINDS``), the message says why."""

    def __init__(self, message: str, kind: str) -> None:
        super().__init__(message)
        self.kind = kind


KINDS = (
    "frame",
    "not finite",
    "out of reach",
    "too many poses",
    "name too long",
    "empty",
    "stamps out of order",
    "in the past",
    "too far ahead",
    "malformed",
    "not a rotation",
    "no orientation task",
)
"""The kinds of refusal (``TargetError.kind``): the node's log is rate-limited per topic and kind, and the
summary's warnings quote the first refusal of each."""

ACCEPTED = "accepted"
REFUSED = "refused"
"""``<topic>/accepted`` (the target as the controller follows it: the same type, stamped with the time of
the first state that follows it, once per change) and ``<topic>/refused`` (diagnostic_msgs/DiagnosticStatus:
why, its kind and the count so far, one per refused target): what the recorder keeps and the report draws."""
REFUSED_KIND_KEY = "kind"
REFUSED_COUNT_KEY = "refused"
"""The ``values`` keys of a ``<topic>/refused`` DiagnosticStatus: the refusal's kind, and how many targets of
that topic the controller has refused so far (the last one recorded is the total)."""


def echo_topic(topic: str, verdict: str) -> str:
    """Where the controller says what it made of a target of ``topic``: ``<topic>/accepted`` or ``/refused``."""
    return f"{topic}/{verdict}"


@dataclass(frozen=True)
class TargetLimits:
    """What one target message may carry and when a path may lie (``max_horizon`` [s] after now)."""

    max_poses: int = 10000  # max_message_elements
    max_name_length: int = 256  # [characters] max_name_length
    max_horizon: float = 3600.0  # [s] targets.max_horizon


@dataclass(frozen=True)
class Goal:
    """Where a task is sent: a point held (one row), or a path (rows at ``times`` [s], linear between,
    the last one held)."""

    times: Vector  # (m,) [s], non-decreasing
    points: Vector  # (m, 3) [m], world

    def at(self, t: float) -> tuple[Vector, Vector]:
        """The goal's position and velocity at t."""
        times, points = self.times, self.points
        if t <= times[0] or len(times) == 1:
            return points[0], np.zeros(3)
        if t >= times[-1]:
            return points[-1], np.zeros(3)
        k = int(np.searchsorted(times, t, side="right")) - 1
        span = times[k + 1] - times[k]
        velocity = (points[k + 1] - points[k]) / span
        return points[k] + velocity * (t - times[k]), velocity


def check_point(what: str, point: Sequence[float], frame_id: str, axes: Sequence[int], reach: Reach | None) -> Vector:
    """The point as an array, or TargetError naming ``what`` and what is wrong with it: another frame
    than world, a non-finite coordinate, or out of the frame's reach along the task's ``axes``
    (``checks.frame_reach``: the reach check the controller does before a run)."""
    if frame_id != "world":
        raise TargetError(
            f"{what} refused: frame {shorten(frame_id)!r}, not 'world' (no TF here: give it in world)", "frame"
        )
    p = np.asarray(point, dtype=float)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise TargetError(f"{what} refused: not finite ({p.tolist()})", "not finite")
    if reach is not None:
        distance = float(np.linalg.norm((p - reach.anchor)[list(axes)]))
        if distance > reach.radius + 1e-9:
            names = ", ".join("xyz"[a] for a in axes)
            raise TargetError(
                f"{what} refused: out of reach, [{', '.join(f'{v:.3g}' for v in p)}] is {distance:.3f} m from "
                f"{reach.joint} along {names}, but the frame is never more than {reach.radius:.3f} m from it",
                "out of reach",
            )
    return p


UNIT_QUATERNION_TOLERANCE = 0.01
"""|norm - 1| a pose's quaternion may have (it is normalised); one further from unit is refused (not a rotation
by mistake: a zero quaternion, a default-constructed message from a library whose w defaults to 0)."""


def check_quaternion(what: str, quaternion: Sequence[float]) -> Vector:
    """The rotation matrix of a quaternion [x, y, z, w] (normalised), or TargetError naming ``what``: a
    non-finite component, or a norm further than UNIT_QUATERNION_TOLERANCE from 1."""
    q = np.asarray(quaternion, dtype=float)
    if q.shape != (4,) or not np.isfinite(q).all():
        raise TargetError(f"{what} refused: orientation not finite ({q.tolist()})", "not finite")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE:
        raise TargetError(
            f"{what} refused: the orientation [x, y, z, w] = {[float(f'{v:.4g}') for v in q]} has norm {norm:.4g}, "
            f"not 1 (within {UNIT_QUATERNION_TOLERANCE:g}): not a rotation",
            "not a rotation",
        )
    x, y, z, w = q / norm
    return np.asarray(pin.Quaternion(w, x, y, z).toRotationMatrix())


def path_goal(times: Sequence[float], points: Sequence[Vector]) -> Goal:
    """A path's goal, refusing an empty one or stamps that go back in time."""
    t = np.asarray(times, dtype=float)
    if t.size == 0:
        raise TargetError("an empty path", "empty")
    if not np.isfinite(t).all() or np.any(np.diff(t) < 0.0):
        raise TargetError("the poses' stamps must be finite and non-decreasing", "stamps out of order")
    return Goal(t, np.asarray(points, dtype=float).reshape(-1, 3))


class Reference:
    """One task's desired position and velocity, moved toward a :class:`Goal` with |v| <= v_max and
    |a| <= a_max: the speed toward the goal is at most sqrt(2 a_max d) (it can stop in the distance d
    left), plus the goal's own velocity (a path), within v_max."""

    def __init__(self, position: Vector, velocity: Vector, t: float, max_velocity: float, max_acceleration: float):
        self.position = np.asarray(position, dtype=float).copy()
        self.velocity = np.asarray(velocity, dtype=float).copy()
        self.t = float(t)
        self.max_velocity = float(max_velocity)
        self.max_acceleration = float(max_acceleration)
        self.goal: Goal | None = None

    def advance(self, t: float) -> tuple[Vector, Vector]:
        """The reference at t (a time at or after the last one): desired position and velocity."""
        dt = float(t) - self.t
        if dt <= 0.0 or self.goal is None:
            return self.position, self.velocity
        self.t = float(t)
        goal, goal_velocity = self.goal.at(self.t)
        error = goal - self.position
        distance = float(np.linalg.norm(error))
        step = self.max_acceleration * dt
        # Within one step's braking of a fixed goal it is there (the last discrete steps would chatter
        # at the scale of a_max dt^2): the velocity changes by at most a_max dt here too.
        if not goal_velocity.any() and distance <= step * dt and np.linalg.norm(self.velocity) <= step:
            self.position, self.velocity = goal.copy(), np.zeros(3)
            return self.position, self.velocity
        self.velocity = _approach(
            error, distance, goal_velocity, self.velocity, self.max_velocity, self.max_acceleration, dt
        )
        self.position = self.position + self.velocity * dt
        return self.position, self.velocity


def _approach(
    error: Vector, distance: float, goal_velocity: Vector, velocity: Vector, v_max: float, a_max: float, dt: float
) -> Vector:
    """The next velocity toward a goal ``error`` away (``distance`` its norm): at most sqrt(2 a_max d) toward
    it plus the goal's own velocity, within v_max, changed by at most a_max dt."""
    wanted = _limit(goal_velocity, v_max)
    if distance > 0.0:
        toward = error / distance * math.sqrt(2.0 * a_max * distance)
        wanted = _limit(wanted + toward, v_max)
    return velocity + _limit(wanted - velocity, a_max * dt)


class OrientationReference:
    """The orientation task's desired rotation R_d (world) and angular velocity w [rad/s] (world axes), turned
    toward a goal rotation as :class:`Reference` moves a point: |w| <= w_max, |dw/dt| <= alpha_max, the error
    the rotation's log map log(R_goal R_d^T) (the law's), R_d <- exp(w dt) R_d each update."""

    def __init__(self, rotation: Vector, t: float, max_angular_velocity: float, max_angular_acceleration: float):
        self.rotation = np.asarray(rotation, dtype=float).copy()
        self.angular_velocity = np.zeros(3)  # the law's R_d is held: it starts at rest
        self.t = float(t)
        self.max_angular_velocity = float(max_angular_velocity)
        self.max_angular_acceleration = float(max_angular_acceleration)
        self.goal: Vector | None = None  # (3, 3)

    def advance(self, t: float) -> tuple[Vector, Vector]:
        """R_d and w at t (a time at or after the last one)."""
        dt = float(t) - self.t
        if dt <= 0.0 or self.goal is None:
            return self.rotation, self.angular_velocity
        self.t = float(t)
        error = np.asarray(pin.log3(self.goal @ self.rotation.T))
        angle = float(np.linalg.norm(error))
        step = self.max_angular_acceleration * dt
        if angle <= step * dt and np.linalg.norm(self.angular_velocity) <= step:  # there (see Reference.advance)
            self.rotation, self.angular_velocity = self.goal.copy(), np.zeros(3)
            return self.rotation, self.angular_velocity
        w = _approach(
            error,
            angle,
            np.zeros(3),
            self.angular_velocity,
            self.max_angular_velocity,
            self.max_angular_acceleration,
            dt,
        )
        self.angular_velocity = w
        self.rotation = np.asarray(pin.exp3(w * dt)) @ self.rotation
        return self.rotation, self.angular_velocity


def _limit(vector: Vector, bound: float) -> Vector:
    norm = float(np.linalg.norm(vector))
    return vector if norm <= bound else vector * (bound / norm)


@dataclass(frozen=True)
class TaskSpec:
    """What a task's targets are checked against: its name in messages, its frame's reach, its axes."""

    what: str  # "hand_target" / "brace_target/<contact>" (the topic a target comes on)
    axes: tuple[int, ...]
    reach: Reach | None


ORIENTATION_ERROR_TOPIC = "hand_orientation_error"
"""The controller's orientation error (geometry_msgs/Vector3Stamped, log(R_d R^T) [rad] in world axes, stamped
with the state it answers): published only with an orientation task (hand.orientation.axes)."""
POSE_TOPIC = "hand_pose_target"
"""The hand's pose target (geometry_msgs/PoseStamped): its position as hand_target's, its orientation the
orientation task's goal."""


@dataclass(frozen=True)
class OrientationSpec:
    """The orientation task as its targets see it: its world axes (empty: none) and the reference's bounds."""

    axes: tuple[int, ...] = ()
    max_angular_velocity: float = 0.5  # [rad/s] targets.max_angular_velocity
    max_angular_acceleration: float = 2.0  # [rad/s^2] targets.max_angular_acceleration


class TaskTargets:
    """The targets of every task (``HAND_TASK``, then ``brace_task(j)``) and the references that lead to them.

    ``point`` and ``path`` check a target and set it as its task's goal (TargetError otherwise; None
    when it equals the current goal: no change); ``references`` advances each retargeted task's
    reference to t. A task's reference starts, at the first update after its first goal, from the
    task's configured path at that instant (``path_at``): no jump in position or velocity."""

    def __init__(
        self,
        tasks: Sequence[TaskSpec],
        max_velocity: float,
        max_acceleration: float,
        limits: TargetLimits = TargetLimits(),
        orientation: OrientationSpec | None = None,
    ) -> None:
        self.tasks = list(tasks)
        self.max_velocity = max_velocity
        self.max_acceleration = max_acceleration
        self.limits = limits
        self.orientation = orientation if orientation is not None else OrientationSpec()
        self.goals: dict[TaskIndex, Goal] = {}
        self.references: dict[TaskIndex, Reference] = {}
        self.orientation_goal: Vector | None = None  # (3, 3) R_goal, world (hand_pose_target)
        self.orientation_reference: OrientationReference | None = None

    def point(self, task: TaskIndex, point: Sequence[float], frame_id: str) -> Goal | None:
        """A point to move to and hold (``hand_target``, ``brace_target/<contact>``), checked."""
        spec = self.tasks[task]
        self.check_size(spec.what, 1, len(frame_id))
        p = check_point(spec.what, point, frame_id, spec.axes, spec.reach)
        return self._set(task, Goal(np.zeros(1), p.reshape(1, 3)))

    def pose(self, point: Sequence[float], quaternion: Sequence[float], frame_id: str) -> Goal | None:
        """A hand pose to move to and hold (``hand_pose_target``): its position as ``point``'s, its orientation
        [x, y, z, w] (normalised) the orientation task's goal. Refused whole (TargetError) if either part is:
        also without an orientation task. None if both are the goals already (no change)."""
        what, spec = POSE_TOPIC, self.tasks[HAND_TASK]
        self.check_size(what, 1, len(frame_id))
        p = check_point(what, point, frame_id, spec.axes, spec.reach)
        rotation = check_quaternion(what, quaternion)
        if not self.orientation.axes:
            raise TargetError(
                f"{what} refused: no orientation task to hold its orientation (set hand.orientation.axes, with "
                "hand.orientation.kp and kd; or send the position alone on hand_target)",
                "no orientation task",
            )
        moved = self._set(HAND_TASK, Goal(np.zeros(1), p.reshape(1, 3)))
        turned = self.turn_to_rotation(rotation)
        return self.goals[HAND_TASK] if moved is not None or turned else None

    def restart(self) -> None:
        """A new run (the states went back in time): every goal kept, each reference to start again at the next
        update from the task's configured path (the orientation's from the law's R_d), as after a first goal."""
        self.references.clear()
        self.orientation_reference = None

    def turn_to(self, quaternion: Sequence[float]) -> bool:
        """The orientation task's goal from now on, a quaternion [x, y, z, w] (hand.orientation.target set while
        running: checked by the configuration); whether it changed."""
        return self.turn_to_rotation(check_quaternion("hand.orientation.target", quaternion))

    def turn_to_rotation(self, rotation: Vector) -> bool:
        """The orientation task's goal from now on, a rotation matrix (world); whether it changed."""
        turned = self.orientation_goal is None or not np.array_equal(self.orientation_goal, rotation)
        self.orientation_goal = rotation
        return turned

    def advance_orientation(self, t: float, held: Callable[[], Vector]) -> tuple[Vector, Vector] | None:
        """The orientation task's R_d and angular velocity at t toward the pose's orientation (None before a
        pose came); ``held()`` gives the law's R_d, where the reference starts (at rest: no kick)."""
        if self.orientation_goal is None:
            return None
        reference = self.orientation_reference
        if reference is None:
            spec = self.orientation
            reference = OrientationReference(held(), t, spec.max_angular_velocity, spec.max_angular_acceleration)
            self.orientation_reference = reference
        reference.goal = self.orientation_goal
        return reference.advance(t)

    def check_size(self, what: str, poses: int, frame_id_length: int) -> None:
        """TargetError unless a message of ``poses`` poses whose longest frame name has
        ``frame_id_length`` characters is within the limits: asked before any per-pose work."""
        limits = self.limits
        if poses > limits.max_poses:
            raise TargetError(
                f"{what} refused: {poses} poses, more than max_message_elements = {limits.max_poses}", "too many poses"
            )
        if frame_id_length > limits.max_name_length:
            message = f"{what} refused: a frame name of {frame_id_length} characters, more than max_name_length"
            raise TargetError(f"{message} = {limits.max_name_length}", "name too long")

    def path(
        self,
        task: TaskIndex,
        times: Sequence[float],
        points: Sequence[Sequence[float]],
        frames: Sequence[str],
        now: float,
        what: str = "hand_path",
    ) -> Goal | None:
        """A timed path (``hand_path``: each pose's stamp [s] the time to be there), checked against
        ``now`` [s] (the time of the state it would be followed from), every point checked."""
        spec = self.tasks[task]
        self.check_size(what, len(points), max((len(f) for f in frames), default=0))
        checked = [
            check_point(f"{what} pose {k}", p, f, spec.axes, spec.reach)
            for k, (p, f) in enumerate(zip(points, frames, strict=True))
        ]
        try:
            goal = path_goal(times, checked)
        except TargetError as exc:
            raise TargetError(f"{what} refused: {exc}", exc.kind) from None
        last, horizon = float(goal.times[-1]), self.limits.max_horizon
        if last < now:
            raise TargetError(
                f"{what} refused: entirely in the past (its last pose at {last:.6g} s, now {now:.6g} s)", "in the past"
            )
        if last > now + horizon:
            raise TargetError(
                f"{what} refused: its last pose at {last:.6g} s is more than targets.max_horizon = {horizon:g} s "
                f"after now ({now:.6g} s; a wall-clock stamp for a sim-time controller?)",
                "too far ahead",
            )
        return self._set(task, goal)

    def _set(self, task: TaskIndex, goal: Goal) -> Goal | None:
        """The task's goal from now on; None if it is that already (no change)."""
        current = self.goals.get(task)
        if (
            current is not None
            and np.array_equal(current.times, goal.times)
            and np.array_equal(current.points, goal.points)
        ):
            return None
        self.goals[task] = goal
        return goal

    def advance(
        self, t: float, path_at: Callable[[TaskIndex, float], tuple[Vector, Vector]]
    ) -> dict[TaskIndex, tuple[Vector, Vector]]:
        """Each retargeted task's desired (position, velocity) at t; ``path_at(task, t)`` gives a task's
        configured path where a reference starts."""
        out = {}
        for task, goal in self.goals.items():
            reference = self.references.get(task)
            if reference is None:
                position, velocity = path_at(task, t)
                reference = Reference(position, velocity, t, self.max_velocity, self.max_acceleration)
                self.references[task] = reference
            reference.goal = goal
            out[task] = reference.advance(t)
        return out
