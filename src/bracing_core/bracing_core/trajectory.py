"""Desired trajectories of task points: a hold, the paper's circle, and waypoints with a smooth profile."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bracing_core.types import Vector


class Trajectory(Protocol):
    def sample(self, t: float) -> tuple[Vector, Vector]:
        """Desired position [m] and velocity [m/s] at time t [s], world."""
        ...


@dataclass(frozen=True)
class Hold:
    point: tuple[float, float, float]

    def sample(self, t: float) -> tuple[Vector, Vector]:
        return np.array(self.point), np.zeros(3)


@dataclass(frozen=True)
class Circle:
    """center + radius (cos th e_u + sin th e_v), th = direction 2 pi t / period + phase.

    The paper's hand: center (0, 1.1, 0.6), radius 0.2, period 10 s, direction -1,
    plane (u, v) = (y, z): y = 1.1 + 0.2 cos(-2 pi t / 10), z = 0.6 + 0.2 sin(-2 pi t / 10).
    """

    center: tuple[float, float, float]
    radius: float  # [m]
    period: float  # [s]
    direction: float = 1.0  # +1 or -1
    phase: float = 0.0  # [rad]
    plane: tuple[int, int] = (1, 2)  # world axis indices (u, v)

    def sample(self, t: float) -> tuple[Vector, Vector]:
        rate = self.direction * 2.0 * math.pi / self.period
        angle = rate * t + self.phase
        u, v = self.plane
        position, velocity = np.array(self.center, dtype=float), np.zeros(3)
        position[u] += self.radius * math.cos(angle)
        position[v] += self.radius * math.sin(angle)
        velocity[u] = -self.radius * rate * math.sin(angle)
        velocity[v] = self.radius * rate * math.cos(angle)
        return position, velocity


@dataclass(frozen=True)
class Waypoints:
    """From ``start`` through each waypoint in turn, rest to rest: each segment of ``segment_time``
    seconds follows the minimum-jerk profile s(u) = 10 u^3 - 15 u^4 + 6 u^5 (zero velocity and
    acceleration at both ends), then the last waypoint is held."""

    start: tuple[float, float, float]
    points: tuple[tuple[float, float, float], ...]
    segment_time: float  # [s]

    def sample(self, t: float) -> tuple[Vector, Vector]:
        path = (self.start, *self.points)
        segment = int(t // self.segment_time) if t > 0.0 else 0
        if segment >= len(self.points):
            return np.array(path[-1], dtype=float), np.zeros(3)
        u = t / self.segment_time - segment
        s = u * u * u * (10.0 + u * (-15.0 + 6.0 * u))
        ds = 30.0 * u * u * (1.0 - u) ** 2 / self.segment_time
        a, b = np.array(path[segment], dtype=float), np.array(path[segment + 1], dtype=float)
        return a + s * (b - a), ds * (b - a)


def _point(values: Sequence[float]) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


@dataclass(frozen=True)
class TrajectoryConfig:
    """A task's desired path as configured (``schema.trajectory_params``): hold, circle or waypoints."""

    kind: str  # hold | circle | waypoints
    center: tuple[float, float, float]
    radius: float  # [m]
    period: float  # [s]
    direction: float  # +1 / -1
    phase: float  # [rad]
    plane: tuple[int, int]  # world axis indices (u, v)
    point: tuple[float, float, float] | None  # hold: None = the first measured position
    waypoints: tuple[tuple[float, float, float], ...]
    segment_time: float  # [s]

    def build(self, start: Sequence[float]) -> Trajectory:
        """The trajectory, given the task point's first measured position ``start``."""
        if self.kind == "circle":
            return Circle(self.center, self.radius, self.period, self.direction, self.phase, self.plane)
        if self.kind == "waypoints":
            return Waypoints(_point(start), self.waypoints, self.segment_time)
        return Hold(self.point if self.point is not None else _point(start))
