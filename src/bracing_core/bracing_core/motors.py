"""DC motors with gear trains, one per joint (paper eqs. 12-24), reflected to the link side."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bracing_core.types import Vector


@dataclass(frozen=True)
class MotorParams:
    """Per-joint motor and gear parameters (arrays of length n, model joint order).

    torque_constant K [V s/rad] (= K_T = K_E), resistance R [ohm], inductance L [H],
    rotor_inertia I_m [kg m^2], gear_ratio k, gear_damping d_m [N m s/rad] (motor side).
    voltage_limit / torque_limit: |command| saturation, 0 = none.
    """

    torque_constant: Vector
    resistance: Vector
    inductance: Vector
    rotor_inertia: Vector
    gear_ratio: Vector
    gear_damping: Vector
    voltage_limit: float = 0.0
    torque_limit: float = 0.0

    def __post_init__(self) -> None:
        n = len(self.torque_constant)
        for name in ("torque_constant", "resistance", "inductance", "rotor_inertia", "gear_ratio", "gear_damping"):
            value = np.asarray(getattr(self, name), dtype=float)
            object.__setattr__(self, name, value)
            if value.shape != (n,):
                raise ValueError(f"motors.{name}: expected {n} values (one per joint), got {value.size}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"motors.{name}: values must be finite, got {value.tolist()}")
        for name in ("resistance", "inductance", "gear_ratio", "torque_constant"):
            if np.any(getattr(self, name) <= 0.0):
                raise ValueError(f"motors.{name}: values must be > 0, got {getattr(self, name).tolist()}")
        for name in ("rotor_inertia", "gear_damping"):
            if np.any(getattr(self, name) < 0.0):
                raise ValueError(f"motors.{name}: values must be >= 0, got {getattr(self, name).tolist()}")
        if self.voltage_limit < 0.0 or self.torque_limit < 0.0:
            raise ValueError("motors.voltage_limit / torque_limit must be >= 0 (0 = no limit)")

    @property
    def n(self) -> int:
        return int(self.torque_constant.size)

    @property
    def reflected_constant(self) -> Vector:
        """K_m = K k: link-side torque per ampere and back-EMF per link rad/s."""
        return self.torque_constant * self.gear_ratio

    @property
    def reflected_inertia(self) -> Vector:
        """J_m = I_m k^2 (diagonal)."""
        return self.rotor_inertia * self.gear_ratio**2

    @property
    def reflected_damping(self) -> Vector:
        """D_m = d_m k^2 (diagonal)."""
        return self.gear_damping * self.gear_ratio**2

    def permuted(self, order: np.ndarray) -> MotorParams:
        """The same motors listed in another joint order."""
        return MotorParams(
            self.torque_constant[order],
            self.resistance[order],
            self.inductance[order],
            self.rotor_inertia[order],
            self.gear_ratio[order],
            self.gear_damping[order],
            self.voltage_limit,
            self.torque_limit,
        )
