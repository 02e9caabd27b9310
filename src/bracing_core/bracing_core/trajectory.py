"""Desired trajectories of task points: a hold, the paper's circle, and waypoints with a smooth
profile (sampled by the engine, ``bracing_engine.Path``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

import bracing_engine as engine
from bracing_core.types import Vector


class Trajectory:
    """A task point's desired path from its first measured position ``start``, sampled by the
    engine's ``Path`` (the one the law runs)."""

    def __init__(self, path: engine.Path, start: Sequence[float]) -> None:
        self.path = path
        self.start = np.asarray(start, dtype=float)

    def sample(self, t: float) -> tuple[Vector, Vector]:
        """Desired position [m] and velocity [m/s] at time t [s], world."""
        position, velocity = self.path.sample(self.start, float(t))
        return position, velocity


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
    start_ramp: float = 0.0  # [s] > 0: the path starts from rest (its time warped over the first start_ramp)

    def path(self) -> engine.Path:
        """The path as the engine runs it.

        hold: ``point``, or the first measured position. circle: center + radius (cos th e_u +
        sin th e_v), th = direction 2 pi t / period + phase (the paper's hand: center (0, 1.1, 0.6),
        radius 0.2, period 10 s, direction -1, plane (y, z)). waypoints: from the first measured
        position through each waypoint in turn, rest to rest, each segment of ``segment_time``
        seconds on the minimum-jerk profile s(u) = 10 u^3 - 15 u^4 + 6 u^5, then the last held. With a
        ``start_ramp`` T > 0, each at the warped time tau(t) = T (x^3 - x^4 / 2), x = t / T, until T, then
        t - T / 2, plus the offset from the first measured position to the path's start times 1 - s(x)
        (minimum jerk): the reference starts where the point is, at rest."""
        u, v = self.plane
        return engine.Path(
            kind=engine.PathKind[self.kind],
            center=np.asarray(self.center, dtype=float),
            radius=self.radius,
            period=self.period,
            direction=self.direction,
            phase=self.phase,
            u=u,
            v=v,
            point=None if self.point is None else np.asarray(self.point, dtype=float),
            waypoints=[np.asarray(w, dtype=float) for w in self.waypoints],
            segment_time=self.segment_time,
            start_ramp=self.start_ramp,
        )

    def build(self, start: Sequence[float]) -> Trajectory:
        """The trajectory, given the task point's first measured position ``start``."""
        return Trajectory(self.path(), start)
