"""DC motors with gear trains, one per joint (paper eqs. 12-24), reflected to the link side.

A revolute joint is driven through the gear ratio k alone; a prismatic joint through k and a
wheel or pinion of radius rho (``transmission_radius``): the joint moves rho per motor-side
radian / k, so every reflected quantity gains 1 / rho per motor shaft (K_m = K k / rho,
J_m = I_m k^2 / rho^2, D_m = d_m k^2 / rho^2) and the joint effort is a force [N].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bracing_core.types import Vector

FIELDS = (
    "torque_constant",
    "resistance",
    "inductance",
    "rotor_inertia",
    "gear_ratio",
    "gear_damping",
    "transmission_radius",
)


@dataclass(frozen=True)
class MotorParams:
    """Per-joint motor and gear parameters (arrays of length n, model joint order).

    torque_constant K [V s/rad] (= K_T = K_E), resistance R [ohm], inductance L [H],
    rotor_inertia I_m [kg m^2], gear_ratio k, gear_damping d_m [N m s/rad] (motor side),
    transmission_radius rho [m] (0: a revolute joint; > 0: a prismatic joint's wheel or pinion).
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
    transmission_radius: Vector = field(default_factory=lambda: np.zeros(0))  # empty: every joint revolute

    def __post_init__(self) -> None:
        n = len(self.torque_constant)
        if not len(self.transmission_radius):
            object.__setattr__(self, "transmission_radius", np.zeros(n))
        for name in FIELDS:
            value = np.asarray(getattr(self, name), dtype=float)
            object.__setattr__(self, name, value)
            if value.shape != (n,):
                raise ValueError(f"motors.{name}: expected {n} values (one per joint), got {value.size}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"motors.{name}: values must be finite, got {value.tolist()}")
        for name in ("resistance", "inductance", "gear_ratio", "torque_constant"):
            if np.any(getattr(self, name) <= 0.0):
                raise ValueError(f"motors.{name}: values must be > 0, got {getattr(self, name).tolist()}")
        for name in ("rotor_inertia", "gear_damping", "transmission_radius"):
            if np.any(getattr(self, name) < 0.0):
                raise ValueError(f"motors.{name}: values must be >= 0, got {getattr(self, name).tolist()}")
        if self.voltage_limit < 0.0 or self.torque_limit < 0.0:
            raise ValueError("motors.voltage_limit / torque_limit must be >= 0 (0 = no limit)")

    @property
    def n(self) -> int:
        return int(self.torque_constant.size)

    @property
    def _ratio(self) -> Vector:
        """Motor radians per joint unit: k per rad (revolute), k / rho per m (prismatic)."""
        radius = self.transmission_radius
        return np.asarray(
            np.where(radius > 0.0, self.gear_ratio / np.where(radius > 0.0, radius, 1.0), self.gear_ratio)
        )

    @property
    def reflected_constant(self) -> Vector:
        """K_m = K k (/ rho): joint torque [N m] or force [N] per ampere, back-EMF per joint rad/s or m/s."""
        return self.torque_constant * self._ratio

    @property
    def reflected_inertia(self) -> Vector:
        """J_m = I_m k^2 (/ rho^2) (diagonal) [kg m^2 or kg]."""
        return self.rotor_inertia * self._ratio**2

    @property
    def reflected_damping(self) -> Vector:
        """D_m = d_m k^2 (/ rho^2) (diagonal)."""
        return self.gear_damping * self._ratio**2

    def selected(self, order: np.ndarray) -> MotorParams:
        """The motors at ``order`` (another joint order, or a subset of the joints)."""
        values = {name: getattr(self, name)[order] for name in FIELDS}
        return MotorParams(**values, voltage_limit=self.voltage_limit, torque_limit=self.torque_limit)
