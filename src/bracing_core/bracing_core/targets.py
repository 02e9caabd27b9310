"""Targets while running, no ROS: a new hand or brace target reached without a kick.

The controller's tasks follow their configured paths (the law's ``Path``, in the engine) until a
target arrives over ROS (``hand_target``, ``hand_path``, ``brace_target/<contact>``). From then on the
task's desired position and velocity come from a :class:`Reference` that starts where the path was at
that instant (position and velocity: no jump) and moves toward the goal with its speed and its
acceleration bounded (``targets.max_velocity`` / ``targets.max_acceleration``). The reference is fed to
the law each update (``engine.Law.set_reference``): the law itself is unchanged, and rollouts, which
have no topics and so no targets, run the configured paths exactly as before.

Why here and not in the engine: a target exists only where a ROS message brings it, the generator is
a few vector operations per update (no model), and the engine keeps one small hook instead of a
second kind of path whose timing depends on when messages come.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from bracing_core.checks import Reach
from bracing_core.types import Vector


class TargetError(ValueError):
    """A target that is refused: out of reach, in another frame, not finite, or a path out of order."""


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
        raise TargetError(f"{what} refused: frame {frame_id!r}, not 'world' (no TF here: give it in world)")
    p = np.asarray(point, dtype=float)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise TargetError(f"{what} refused: not finite ({p.tolist()})")
    if reach is not None:
        distance = float(np.linalg.norm((p - reach.anchor)[list(axes)]))
        if distance > reach.radius + 1e-9:
            names = ", ".join("xyz"[a] for a in axes)
            raise TargetError(
                f"{what} refused: out of reach, [{', '.join(f'{v:.3g}' for v in p)}] is {distance:.3f} m from "
                f"{reach.joint} along {names}, but the frame is never more than {reach.radius:.3f} m from it"
            )
    return p


def path_goal(times: Sequence[float], points: Sequence[Vector]) -> Goal:
    """A path's goal, refusing an empty one or stamps that go back in time."""
    t = np.asarray(times, dtype=float)
    if t.size == 0:
        raise TargetError("an empty path")
    if not np.isfinite(t).all() or np.any(np.diff(t) < 0.0):
        raise TargetError("the poses' stamps must be finite and non-decreasing")
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
        wanted = _limit(goal_velocity, self.max_velocity)
        if distance > 0.0:
            toward = error / distance * math.sqrt(2.0 * self.max_acceleration * distance)
            wanted = _limit(wanted + toward, self.max_velocity)
        self.velocity = self.velocity + _limit(wanted - self.velocity, step)
        self.position = self.position + self.velocity * dt
        return self.position, self.velocity


def _limit(vector: Vector, bound: float) -> Vector:
    norm = float(np.linalg.norm(vector))
    return vector if norm <= bound else vector * (bound / norm)


@dataclass(frozen=True)
class TaskSpec:
    """What a task's targets are checked against: its name in messages, its frame's reach, its axes."""

    what: str  # "hand_target" / "brace_target/<contact>" (the topic a target comes on)
    axes: tuple[int, ...]
    reach: Reach | None


class TaskTargets:
    """The targets of every task (0 the hand, 1 + j brace j) and the references that lead to them.

    ``set_goal`` takes a checked goal (TargetError otherwise); ``references`` advances each retargeted
    task's reference to t. A task's reference starts, at the first update after its first goal, from
    the task's configured path at that instant (``path_at``): no jump in position or velocity."""

    def __init__(self, tasks: Sequence[TaskSpec], max_velocity: float, max_acceleration: float) -> None:
        self.tasks = list(tasks)
        self.max_velocity = max_velocity
        self.max_acceleration = max_acceleration
        self.goals: dict[int, Goal] = {}
        self.references: dict[int, Reference] = {}

    def point(self, task: int, point: Sequence[float], frame_id: str) -> Goal:
        """A point to move to and hold (``hand_target``, ``brace_target/<contact>``), checked."""
        spec = self.tasks[task]
        p = check_point(spec.what, point, frame_id, spec.axes, spec.reach)
        goal = Goal(np.zeros(1), p.reshape(1, 3))
        self.goals[task] = goal
        return goal

    def path(self, task: int, times: Sequence[float], points: Sequence[Sequence[float]], frames: Sequence[str]) -> Goal:
        """A timed path (``hand_path``: each pose's stamp [s] the time to be there), every point checked."""
        spec = self.tasks[task]
        checked = [
            check_point(f"{spec.what} pose {k}", p, f, spec.axes, spec.reach)
            for k, (p, f) in enumerate(zip(points, frames, strict=True))
        ]
        try:
            goal = path_goal(times, checked)
        except TargetError as exc:
            raise TargetError(f"{spec.what} refused: {exc}") from None
        self.goals[task] = goal
        return goal

    def advance(
        self, t: float, path_at: Callable[[int, float], tuple[Vector, Vector]]
    ) -> dict[int, tuple[Vector, Vector]]:
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
