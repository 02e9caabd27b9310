"""Desired trajectories of task points: the paper's circle and a hold."""

from __future__ import annotations

import math
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
