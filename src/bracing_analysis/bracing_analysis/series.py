"""A recorded run's time series (``BagSeries``: what ``bag.read_series`` reads from a bag, and what an
in-process run records; no rclpy needed).

Times are in seconds relative to ``t0``, the first ``joint_states`` stamp (the first
stamp of any recorded message if there is no ``joint_states``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bracing_analysis.surfaces import Shape

FloatArray = NDArray[np.float64]


def _empty(cols: int = 0) -> FloatArray:
    return np.zeros((0, cols)) if cols else np.zeros(0)


@dataclass
class ContactSeries:
    """Everything recorded about one contact (bracing point)."""

    name: str
    # From `contacts` (the simulator):
    t: FloatArray = field(default_factory=_empty)  # [s]
    normal_force: FloatArray = field(default_factory=_empty)  # f_n [N]
    friction_force: FloatArray = field(default_factory=_empty)  # f_t [N]
    residual: FloatArray = field(default_factory=_empty)  # C = n . r - c [m]
    active: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    position: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    normal: FloatArray = field(default_factory=lambda: _empty(3))  # surface normal at the contact
    slip_velocity: FloatArray = field(default_factory=lambda: _empty(3))  # s = J dq, tangential [m/s]
    # From `contact_wrench/<name>` (the simulator): force on the robot, world axes:
    t_force: FloatArray = field(default_factory=_empty)  # [s]
    force: FloatArray = field(default_factory=lambda: _empty(3))  # [N]
    # From `controller_state` (the controller):
    t_ctrl: FloatArray = field(default_factory=_empty)  # [s]
    normal_force_desired: FloatArray = field(default_factory=_empty)  # f_nd [N]
    brace_desired: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    brace_actual: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    brace_measured: FloatArray = field(default_factory=lambda: _empty(3))  # [m] with sensors: the controller's view
    # contacts and controller_state samples with the same header stamp:
    t_matched: FloatArray = field(default_factory=_empty)  # [s]
    normal_force_error: FloatArray = field(default_factory=_empty)  # f_n - f_nd [N]


@dataclass(frozen=True)
class ParameterChange:
    """A node's parameters changed while it ran (recorded from /parameter_events)."""

    t: float  # [s], the run's time base
    node: str  # fully qualified (/bracing_controller)
    values: dict[str, Any]  # name -> new value (None: deleted)

    def text(self) -> str:
        """``hand.kp = [150.0, 150.0]``, one per changed parameter."""
        return ", ".join(f"{name} = {value}" for name, value in self.values.items())


@dataclass(frozen=True)
class TargetSent:
    """A target the controller accepted while it ran (hand_target, hand_path, brace_target/<contact>), as
    it echoed it on ``<target>/accepted``; in a bag from before it did, a target as it was sent."""

    t: float  # [s], the run's time base: when the recorder got it (the sim time of the last /clock)
    task: str  # "hand" or the contact's name
    points: FloatArray  # (poses, 3) [m], world (one row for a point)
    times: FloatArray  # (poses,) [s], the run's time base: a path's pose stamps; a point's = t


@dataclass(frozen=True)
class TargetRefused:
    """A target the controller refused while it ran (recorded from ``<target>/refused``)."""

    t: float  # [s], the run's time base: when the recorder got the refusal
    topic: str  # the target's topic: hand_target, hand_path, brace_target/<contact>
    kind: str  # the check it failed (bracing_core.targets.KINDS)
    why: str  # the controller's words
    count: int  # targets of that topic refused so far, this one included


@dataclass
class BagSeries:
    """Time series of one run (see the module docstring for the time base)."""

    t0_ns: int = 0
    joint_t: FloatArray = field(default_factory=_empty)  # joint_states stamps [s]
    joint_names: list[str] = field(default_factory=list)
    joint_position: FloatArray = field(default_factory=lambda: _empty(1))  # (states, joints) [rad or m]
    robot_description: str | None = None  # the URDF recorded on robot_description (newer bags)
    t: FloatArray = field(default_factory=_empty)  # controller_state stamps [s]
    hand_desired: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    hand_actual: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    # with sensors (truth.py): hand_actual is the true position, this what the controller believed
    hand_measured: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    contacts: dict[str, ContactSeries] = field(default_factory=dict)
    motor_t: FloatArray = field(default_factory=_empty)  # motor_state stamps [s]
    energy_consumed: FloatArray = field(default_factory=_empty)  # [J]
    energy_net: FloatArray = field(default_factory=_empty)  # [J]
    copper_loss: FloatArray = field(default_factory=_empty)  # [J]
    motor_names: list[str] = field(default_factory=list)  # motor_state's joint names
    # (motor_state messages, motors) winding temperatures [degC]; NaN rows where a message has none (torque
    # input, the thermal model off, a bag from before it), so no columns at all when none has any
    motor_temperature: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    topic_counts: dict[str, int] = field(default_factory=dict)  # messages per topic
    input_mode: str | None = None  # motor_command's mode ("voltage", "torque"); None if none was recorded
    scenario: str | None = None  # the scenario's name (bag metadata, the recorder's --scenario); None: unknown
    surfaces: dict[str, Shape] = field(default_factory=dict)  # each contact's surface (bag metadata)
    parameter_changes: list[ParameterChange] = field(default_factory=list)  # the controller's, in time order
    # The world axes ("x", "y", "z") of the controller's tasks (bag metadata): the hand's (None: not said) and
    # each braced contact's (a contact not listed: not said). The report draws each (drawing.hand_axes).
    hand_axes: list[str] | None = None
    brace_task_axes: dict[str, list[str]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)  # what the nodes warned about (run_status), in time order
    targets: list[TargetSent] = field(default_factory=list)  # accepted while it ran (older bags: sent), in time order
    targets_refused: list[TargetRefused] = field(default_factory=list)  # refused while it ran, in time order
    # The controller's commands (rows: answers; columns: motor_names) [V, N m or N] and each joint's |command|
    # saturation (0: none); empty where not recorded (summary.json's saturation_fraction is then null).
    command: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    # the hand frame's orientation error per controller_state row [rad], world axes; (t, 0) or empty without the task
    hand_orientation_error: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    command_limit: dict[str, float] = field(default_factory=dict)
    # a differential drive's rolling residual max |A v| per state [m/s] (bracing_core.base); empty: not recorded
    base_rolling_residual: FloatArray = field(default_factory=_empty)


def scenario_name(series: BagSeries) -> str:
    """The run's scenario: as the bag notes it, else its robot's name (URDF), else unknown."""
    if series.scenario:
        return series.scenario
    robot = re.search(r"<robot\b[^>]*\bname\s*=\s*[\"']([^\"']+)", series.robot_description or "")
    return f"robot {robot.group(1)}" if robot else "unknown scenario"
