"""Typed configuration of the controller, built once from ROS parameters and validated."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bracing_sim.config import (
    CONTACT_FIELDS,
    SHARED_PARAMETERS,
    SharedConfig,
    axes_indices,
)
from bracing_sim.params import ConfigError, Params, check_known, get_bool, get_float, get_floats, get_str, get_strs

CONTROLLER_PARAMETERS: dict[str, object] = {
    "hand.frame": "hand",
    "hand.axes": ["y", "z"],
    "hand.kp": [],
    "hand.kd": [],
    "hand.trajectory.type": "circle",
    "hand.trajectory.center": [],
    "hand.trajectory.radius": 0.0,
    "hand.trajectory.period": 10.0,
    "hand.trajectory.direction": 1.0,
    "hand.trajectory.phase": 0.0,
    "hand.trajectory.plane": ["y", "z"],
    "hand.trajectory.point": [],
    "voltage_gain": [],
    "gravity_compensation": False,
    "damping_lambda": 1e-6,
    "wait_for_recorder": False,
    "log_throttle_period": 1.0,
}


@dataclass(frozen=True)
class TrajectoryConfig:
    kind: str  # circle | hold
    center: tuple[float, float, float]
    radius: float
    period: float
    direction: float
    phase: float
    plane: tuple[int, int]
    point: tuple[float, float, float] | None  # hold: None = initial hand position


@dataclass(frozen=True)
class HandTaskConfig:
    frame: str
    axes: tuple[int, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    trajectory: TrajectoryConfig


@dataclass(frozen=True)
class ControllerConfig:
    shared: SharedConfig
    hand: HandTaskConfig
    voltage_gain: tuple[float, ...]  # K_V diagonal, robot.joint_names order
    gravity_compensation: bool  # add g(q) to l (not in the paper)
    damping_lambda: float  # damped-inverse regularisation for a near-singular B
    wait_for_recorder: bool = False  # answer the first state only once a recorder subscribes to both outputs
    log_throttle_period: float = 1.0  # [s] wall; at most one report per kind of bad input per period

    @property
    def task_dimension(self) -> int:
        return len(self.hand.axes) + sum(len(c.brace_axes) for c in self.shared.contacts)

    @classmethod
    def from_params(cls, params: Params, search_dirs: Sequence[Path] = ()) -> ControllerConfig:
        check_known(params, [*SHARED_PARAMETERS, *CONTROLLER_PARAMETERS], {"contacts.": CONTACT_FIELDS})
        shared = SharedConfig.from_params(params, search_dirs)
        n, p = len(shared.joint_names), len(shared.contacts)
        axes_names = get_strs(params, "hand.axes", ["y", "z"])
        axes = axes_indices("hand.axes", axes_names)
        hint = f"one per hand axis {list(axes_names)}"
        kind = get_str(params, "hand.trajectory.type", "circle", choices=("circle", "hold"))
        plane = axes_indices("hand.trajectory.plane", get_strs(params, "hand.trajectory.plane", ["y", "z"]))
        if len(plane) != 2:
            raise ConfigError(f"hand.trajectory.plane: expected two axes, got {len(plane)}")
        point = get_floats(params, "hand.trajectory.point", [])
        if point and len(point) != 3:
            raise ConfigError(f"hand.trajectory.point: expected [x, y, z] or an empty list, got {list(point)}")
        if kind == "circle":
            center = get_floats(params, "hand.trajectory.center", None, length=3)
            radius = get_float(params, "hand.trajectory.radius", None, minimum=0.0)
            period = get_float(params, "hand.trajectory.period", 10.0, positive=True)
            direction = get_float(params, "hand.trajectory.direction", 1.0)
            if direction not in (-1.0, 1.0):
                raise ConfigError(f"hand.trajectory.direction: expected +1 or -1, got {direction}")
        else:
            center, radius, period, direction = (0.0, 0.0, 0.0), 0.0, 1.0, 1.0
        trajectory = TrajectoryConfig(
            kind=kind,
            center=(center[0], center[1], center[2]),
            radius=radius,
            period=period,
            direction=direction,
            phase=get_float(params, "hand.trajectory.phase", 0.0),
            plane=(plane[0], plane[1]),
            point=(point[0], point[1], point[2]) if point else None,
        )
        hand = HandTaskConfig(
            frame=get_str(params, "hand.frame", "hand"),
            axes=axes,
            kp=get_floats(params, "hand.kp", None, length=len(axes), length_hint=hint),
            kd=get_floats(params, "hand.kd", None, length=len(axes), length_hint=hint),
            trajectory=trajectory,
        )
        voltage_gain = get_floats(
            params, "voltage_gain", [1.0] * n, length=n, length_hint=f"one per joint of robot.joint_names ({n})"
        )
        if any(k <= 0.0 for k in voltage_gain):
            raise ConfigError(f"voltage_gain: K_V must be positive definite, got {list(voltage_gain)}")
        config = cls(
            shared=shared,
            hand=hand,
            voltage_gain=voltage_gain,
            gravity_compensation=get_bool(params, "gravity_compensation", False),
            damping_lambda=get_float(params, "damping_lambda", 1e-6, positive=True),
            wait_for_recorder=get_bool(params, "wait_for_recorder", False),
            log_throttle_period=get_float(params, "log_throttle_period", 1.0, minimum=0.0),
        )
        if config.task_dimension > n - p:
            raise ConfigError(
                f"task dimension {config.task_dimension} (hand {len(axes)} + brace "
                f"{config.task_dimension - len(axes)}) exceeds n - p = {n} - {p} = {n - p}: "
                "the null space of B cannot hold them; remove hand.axes or contacts.<name>.brace_axes"
            )
        return config
