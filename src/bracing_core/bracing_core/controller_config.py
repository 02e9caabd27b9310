"""Typed configuration of the controller, built once from ROS parameters and validated."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bracing_core import schema
from bracing_core.base import BASE_JOINTS
from bracing_core.config import SharedConfig
from bracing_core.contact_config import axes_indices, trajectory_from_values
from bracing_core.params import ConfigError, Params
from bracing_core.trajectory import TrajectoryConfig

if TYPE_CHECKING:
    from bracing_core.schema.typed_values import ControllerValues
else:  # the class the schema derives (tools/values_stubs.py declares it to mypy)
    ControllerValues = schema.NODE_VALUES["controller"]


@dataclass(frozen=True)
class HandTaskConfig:
    frame: str
    axes: tuple[int, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    trajectory: TrajectoryConfig
    ki: tuple[float, ...] = ()  # one per hand axis; empty: no integral action


@dataclass(frozen=True)
class OrientationConfig:
    """hand.orientation.*: the hand frame's orientation held about world axes (no axes: none)."""

    axes: tuple[int, ...] = ()
    kp: tuple[float, ...] = ()
    kd: tuple[float, ...] = ()
    ki: tuple[float, ...] = ()  # empty: no integral
    target: tuple[float, float, float, float] | None = None  # [x, y, z, w], normalised; None: the first measured

    @classmethod
    def from_values(cls, values: schema.Values) -> OrientationConfig:
        given = values.params.hand.orientation
        axes = axes_indices("hand.orientation.axes", given.axes)
        target = given.target
        quaternion = None
        if target:
            norm = math.sqrt(sum(v * v for v in target))
            if not norm > 1e-9:
                raise ConfigError(f"hand.orientation.target: a quaternion [x, y, z, w] of norm > 0, got {list(target)}")
            quaternion = (target[0] / norm, target[1] / norm, target[2] / norm, target[3] / norm)
        return cls(axes, tuple(given.kp), tuple(given.kd), tuple(given.ki), quaternion)


@dataclass(frozen=True)
class ControllerConfig(ControllerValues):
    """The controller node's configuration: its typed values (a field per parameter of ``schema.CONTROLLER`` and
    the shared ones, units and meaning there), and what is built from them: the shared plant, the hand task
    (axes as world indices, its path) and the orientation task (the target normalised)."""

    shared: SharedConfig
    hand_task: HandTaskConfig
    orientation: OrientationConfig  # hand.orientation.*

    @property
    def task_dimension(self) -> int:
        braces = sum(len(c.brace_axes) for c in self.shared.braced_contacts)
        return len(self.hand_task.axes) + len(self.orientation.axes) + braces

    @classmethod
    def from_params(cls, params: Params, search_dirs: Sequence[Path] = ()) -> ControllerConfig:
        """Validated against ``schema.CONTROLLER`` (and the shared parameters), with the law's
        cross-checks: +/-1 direction, positive K_V, task dimension <= n - p."""
        return cls.from_values(schema.read("controller", params), search_dirs)

    @classmethod
    def from_values(cls, values: schema.Values[ControllerValues], search_dirs: Sequence[Path] = ()) -> ControllerConfig:
        shared = SharedConfig.from_values(values, search_dirs)
        n = len([name for name in shared.joint_names if name not in shared.locked_joints])  # the moving ones
        p = len(shared.braced_contacts)
        given = values.params
        axes = axes_indices("hand.axes", given.hand.axes)
        trajectory = trajectory_from_values("hand.trajectory.", given.hand.trajectory, given.hand.trajectory.point)
        hand = HandTaskConfig(given.hand.frame, axes, given.hand.kp, given.hand.kd, trajectory, tuple(given.hand.ki))
        voltage_gain = given.voltage_gain
        if any(k <= 0.0 for k in voltage_gain):
            raise ConfigError(f"voltage_gain: K_V must be positive definite, got {list(voltage_gain)}")
        config = cls(
            **schema.fields_of(given),
            shared=shared,
            hand_task=hand,
            orientation=OrientationConfig.from_values(values),
        )
        check_effort_forward(config)
        check_base_command(config)
        if config.task_dimension > n - p:
            turn = len(config.orientation.axes)
            parts = f"hand {len(axes)}" + (f" + orientation {turn}" if turn else "")
            raise ConfigError(
                f"task dimension {config.task_dimension} ({parts} + brace {config.task_dimension - len(axes) - turn}) "
                f"exceeds n - p = {n} - {p} = {n - p}: the null space of B cannot hold them; remove hand.axes"
                + (", hand.orientation.axes" if turn else "")
                + " or contacts.<name>.brace_axes"
            )
        return config


def check_effort_forward(config: ControllerConfig) -> None:
    """effort_forward sends the torque law's efforts: torque input, and joints that are the arm's moving ones."""
    if config.command_output != "effort_forward":
        return
    if config.shared.input_mode.value != "torque":
        raise ConfigError("command_output: effort_forward sends efforts (eq. 38): set robot.input_mode to torque")
    joints = config.effort_command_joints
    if not joints:
        return
    moving = [j for j in config.shared.joint_names if j not in config.shared.locked_joints]
    if len(set(joints)) != len(joints) or sorted(joints) != sorted(moving):
        raise ConfigError(
            f"effort_command_joints: {list(joints)} must name each moving joint once, in any order ({moving})"
        )


def check_base_command(config: ControllerConfig) -> None:
    """base_command cmd_vel needs a mobile base: base_x, base_y and base_yaw among the moving joints, or a
    differential drive whose wheels turn."""
    if config.base_command != "cmd_vel":
        return
    shared = config.shared
    moving = [j for j in shared.joint_names if j not in shared.locked_joints]
    missing = [j for j in BASE_JOINTS if j not in moving]
    rolling = shared.wheels is not None and not set(shared.wheels.names) <= set(shared.locked_joints)
    if missing and not rolling:  # a differential drive's base joints are the model's, not listed: its wheels turn
        raise ConfigError(
            f"base_command: cmd_vel drives a mobile base, but {missing} are not moving joints (set robot.base to "
            "planar or diff_drive, or base_command to task)"
        )
