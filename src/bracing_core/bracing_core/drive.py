"""A motor drive's current loop, no ROS: a link-side torque request -> a terminal voltage.

A ros2_control effort interface commands torque; the simulated motors in voltage mode take a
terminal voltage (docs/model.md, eqs. 12-24), so the simulator puts a drive between them, as a real
servo amplifier does. Per joint, with K_m the reflected torque constant, R and L the winding's
resistance (R_20) and inductance:

    i* = tau* / K_m                                   (the current the torque request needs)
    v  = K_m dq + kp (i* - i) + ki * integral (i* - i) dt,   |v| <= voltage_limit (0 = none)

The back-EMF K_m dq is fed forward; the integral stops while the voltage saturates (anti-windup).
With kp = L w and ki = R w (the defaults, from ``motor_drive.bandwidth`` w), the PI zero cancels the
winding's pole R / L and the closed loop is first order: i / i* = w / (s + w), a current step
reaches 1 - exp(-w t) of its value (docs/model.md; test/test_joint_commands.py checks it by hand).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bracing_core.types import Vector


@dataclass(frozen=True)
class DriveGains:
    """The current loop's gains per joint (model order): kp [V/A], ki [V/(A s)]."""

    kp: Vector
    ki: Vector

    @classmethod
    def from_bandwidth(
        cls,
        bandwidth: float,
        inductance: Vector,
        resistance: Vector,
        kp: Sequence[float] | Vector = (),
        ki: Sequence[float] | Vector = (),
    ) -> DriveGains:
        """kp = L w and ki = R w (the pole cancelled: a first-order loop of bandwidth w [rad/s]),
        unless given (``motor_drive.kp`` / ``motor_drive.ki``, same order as L and R)."""
        kp_ = np.asarray(kp, dtype=float) if len(kp) else bandwidth * np.asarray(inductance, dtype=float)
        ki_ = np.asarray(ki, dtype=float) if len(ki) else bandwidth * np.asarray(resistance, dtype=float)
        return cls(kp_, ki_)


class CurrentLoopDrive:
    """The drive of every joint: ``voltage`` for one control period, ``commit`` once it is applied."""

    def __init__(self, gains: DriveGains, torque_constant: Vector, voltage_limit: float = 0.0) -> None:
        self.kp = np.asarray(gains.kp, dtype=float)
        self.ki = np.asarray(gains.ki, dtype=float)
        self.torque_constant = np.asarray(torque_constant, dtype=float)  # K_m, link side [N m/A or N/A]
        self.voltage_limit = float(voltage_limit)
        self.integral = np.zeros_like(self.torque_constant)  # integral of (i* - i) dt [A s]
        self._pending = self.integral

    def voltage(self, torque: Vector, current: Vector, velocity: Vector, dt: float) -> Vector:
        """The terminal voltage [V] for the torque request ``torque`` at the measured ``current`` [A]
        and joint ``velocity``, held for ``dt`` [s]. The loop's state advances only on ``commit``."""
        error = np.asarray(torque, dtype=float) / self.torque_constant - np.asarray(current, dtype=float)
        integral = self.integral + error * dt
        v = self.torque_constant * np.asarray(velocity, dtype=float) + self.kp * error + self.ki * integral
        limit = self.voltage_limit
        if limit > 0.0:
            saturated = np.abs(v) > limit
            winding = saturated & (np.sign(v) == np.sign(error))
            integral = np.where(winding, self.integral, integral)  # anti-windup: hold while it pushes the limit
            v = np.clip(v, -limit, limit)
        self._pending = integral
        return np.asarray(v)

    def commit(self) -> None:
        """The last ``voltage`` was applied: its period counts (a refused step does not)."""
        self.integral = self._pending
