"""DC motors with gear trains, one per joint (paper eqs. 12-24), reflected to the link side.

A revolute joint is driven through the gear ratio k alone; a prismatic joint through k and a
wheel or pinion of radius rho (``transmission_radius``): the joint moves rho per motor-side
radian / k, so every reflected quantity gains 1 / rho per motor shaft (K_m = K k / rho,
J_m = I_m k^2 / rho^2, D_m = d_m k^2 / rho^2) and the joint effort is a force [N].

Thermal model (docs/model.md, Motor thermal model): one winding temperature T per motor,
C_th dT/dt = R(T) i^2 - (T - T_a) / R_th with R(T) = R_20 (1 + alpha (T - 20 degC)); ``resistance``
is R_20. The defaults are chosen for Table 1's motors (the paper gives none): see below.
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
    "thermal_resistance",
    "heat_capacity",
)

# Thermal defaults, chosen (the paper gives none) for motors like Table 1's: K = 0.2 N m/A, R = 0.6 ohm
# and I_m = 1.64e-4 kg m^2 are those of a 150-250 W brushed DC motor (maxon RE 50 / RE 65 class). Such
# datasheets give winding-to-housing ~1 K/W and housing-to-ambient ~2 K/W, and a winding time constant
# (winding to housing) of ~70 s. One lumped node per motor: R_th the whole path to ambient (3 K/W, so the
# steady state is right) and C_th the winding's own capacity (70 s / 1 K/W = 70 J/K, so the first
# minute, where the winding heats before its housing does, is right); tau = R_th C_th = 210 s. Leaving
# the housing's mass out overestimates the temperature between minutes and half an hour: on the safe side.
THERMAL_RESISTANCE = 3.0  # R_th [K/W], winding to ambient
HEAT_CAPACITY = 70.0  # C_th [J/K], the winding
AMBIENT_TEMPERATURE = 20.0  # T_a [degC], every winding's temperature at the start; R(T_a) = R_20, the paper's R
COPPER_TEMPERATURE_COEFFICIENT = 0.00393  # alpha [1/K] of copper, R(T) = R_20 (1 + alpha (T - 20 degC))
_THERMAL_DEFAULTS = {"thermal_resistance": THERMAL_RESISTANCE, "heat_capacity": HEAT_CAPACITY}


@dataclass(frozen=True)
class MotorParams:
    """Per-joint motor and gear parameters (arrays of length n, model joint order).

    torque_constant K [V s/rad] (= K_T = K_E), resistance R [ohm], inductance L [H],
    rotor_inertia I_m [kg m^2], gear_ratio k, gear_damping d_m [N m s/rad] (motor side),
    transmission_radius rho [m] (0: a revolute joint; > 0: a prismatic joint's wheel or pinion).
    voltage_limit: |v| saturation [V], 0 = none; torque_limit: each joint's |tau| saturation [N m or N] (one value
    is every joint's), 0 = none.
    thermal: the winding temperatures are integrated (voltage mode) and R = R(T); resistance is then
    R_20. thermal_resistance R_th [K/W], heat_capacity C_th [J/K] (empty: the defaults above),
    ambient_temperature T_a [degC], temperature_coefficient alpha [1/K].
    """

    torque_constant: Vector
    resistance: Vector
    inductance: Vector
    rotor_inertia: Vector
    gear_ratio: Vector
    gear_damping: Vector
    voltage_limit: float = 0.0
    torque_limit: Vector = field(default_factory=lambda: np.zeros(1))  # one value (every joint's) or one per joint
    transmission_radius: Vector = field(default_factory=lambda: np.zeros(0))  # empty: every joint revolute
    thermal_resistance: Vector = field(default_factory=lambda: np.zeros(0))  # empty: THERMAL_RESISTANCE each
    heat_capacity: Vector = field(default_factory=lambda: np.zeros(0))  # empty: HEAT_CAPACITY each
    thermal: bool = True
    ambient_temperature: float = AMBIENT_TEMPERATURE
    temperature_coefficient: float = COPPER_TEMPERATURE_COEFFICIENT

    def __post_init__(self) -> None:
        n = len(self.torque_constant)
        limit = np.asarray(self.torque_limit, dtype=float).reshape(-1)
        if limit.size not in (1, n):
            raise ValueError(f"motors.torque_limit: expected one value or {n} (one per joint), got {limit.tolist()}")
        object.__setattr__(self, "torque_limit", np.full(n, limit[0]) if limit.size == 1 else limit)
        if not len(self.transmission_radius):
            object.__setattr__(self, "transmission_radius", np.zeros(n))
        for name, default in _THERMAL_DEFAULTS.items():
            if not len(getattr(self, name)):
                object.__setattr__(self, name, np.full(n, default))
        for name in FIELDS:
            value = np.asarray(getattr(self, name), dtype=float)
            object.__setattr__(self, name, value)
            if value.shape != (n,):
                raise ValueError(f"motors.{name}: expected {n} values (one per joint), got {value.size}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"motors.{name}: values must be finite, got {value.tolist()}")
        positive = ("resistance", "inductance", "gear_ratio", "torque_constant", "thermal_resistance", "heat_capacity")
        for name in positive:
            if np.any(getattr(self, name) <= 0.0):
                raise ValueError(f"motors.{name}: values must be > 0, got {getattr(self, name).tolist()}")
        for name in ("rotor_inertia", "gear_damping", "transmission_radius"):
            if np.any(getattr(self, name) < 0.0):
                raise ValueError(f"motors.{name}: values must be >= 0, got {getattr(self, name).tolist()}")
        if self.voltage_limit < 0.0 or np.any(self.torque_limit < 0.0) or not np.all(np.isfinite(self.torque_limit)):
            raise ValueError("motors.voltage_limit / torque_limit must be >= 0 (0 = no limit)")
        if not (np.isfinite(self.ambient_temperature) and np.isfinite(self.temperature_coefficient)):
            raise ValueError("motors.ambient_temperature / temperature_coefficient must be finite")
        if self.temperature_coefficient < 0.0:
            raise ValueError("motors.temperature_coefficient must be >= 0")

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
        return MotorParams(
            **values,
            voltage_limit=self.voltage_limit,
            torque_limit=self.torque_limit[order],
            thermal=self.thermal,
            ambient_temperature=self.ambient_temperature,
            temperature_coefficient=self.temperature_coefficient,
        )
