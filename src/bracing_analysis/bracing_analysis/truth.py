"""Measured against true: a run whose simulator measures through sensors (``sensors.*``) publishes what
its controller received on the usual topics and the truth on ``ground_truth/joint_states`` (no rclpy).

The controller's ``controller_state`` says where it *believes* the hand and the brace points are (from
the positions it received); the paper's metrics judge where they *are*. ``bag.apply_ground_truth``
puts the true positions (the task frames' kinematics at the true joint positions, ``true_positions``)
in the series' ``hand_actual`` and each contact's ``brace_actual``, and keeps the believed ones beside
them (``hand_measured``, ``brace_measured``): the summary's metrics are then the truth's, as the rollout's are.
The task frames come from the scenario (the recorder keeps them in the bag's metadata, ``TASK_FRAMES_KEY``), as do
the tasks' world axes (``TASK_AXES_KEY``: the report draws the hand and each brace point along each of them).
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bracing_core import schema
from bracing_core.overrides import CONTROLLER, SIMULATOR
from bracing_core.params import ConfigError, resolve_file
from bracing_core.rcl_yaml import load_params_file
from bracing_core.sensing import GROUND_TRUTH

TASK_FRAMES_KEY = "bracing.task_frames"
"""Bag metadata (custom_data): JSON {"hand": frame, "braces": {contact: frame}} of the controller's tasks."""
TASK_AXES_KEY = "bracing.task_axes"
"""Bag metadata (custom_data): JSON {"hand": [axis, ...], "braces": {contact: [axis, ...]}}, the world axes
("x", "y", "z") of the controller's tasks (``hand.axes``, ``contacts.<name>.brace_axes``)."""
INPUT_MODE_KEY = "bracing.input_mode"
"""Bag metadata (custom_data): the controller's ``input_mode`` (voltage | torque), the report's for a bag
without motor_command (a ros2_control robot's: the controller's efforts go to its forward controller)."""
COMMAND_LIMIT_KEY = "bracing.command_limit"
"""Bag metadata (custom_data): JSON {joint: |command| saturation} of the simulator's motors (0: none; only
written where a joint has one): summary.json's saturation_fraction."""
HAND = "hand"
AXES = ("x", "y", "z")


def read_task_notes(files: Sequence[str | Path], ground_truth: bool) -> dict[str, str]:
    """What the recorder notes in the bag's metadata of the controller in these params files (later files
    win), read once: its task axes (``TASK_AXES_KEY``), its input mode (``INPUT_MODE_KEY``) and, with
    ``ground_truth``, its task frames (``TASK_FRAMES_KEY``). Raises ConfigError."""
    params: dict[str, Any] = {}
    for file in files:
        params.update(load_params_file(file, CONTROLLER))
    return task_notes_from_values(schema.read("controller", params), ground_truth)


def task_notes_from_values(values: schema.Values, ground_truth: bool) -> dict[str, str]:
    """``read_task_notes`` of the controller's typed values (``schema.read``)."""
    given = values.params
    braced = {name: own for name, own in values.contacts.items() if own.desired_normal_force is not None}
    frames = {HAND: given.hand.frame, "braces": {name: own.frame for name, own in braced.items()}}
    axes = {
        HAND: list(given.hand.axes),
        "braces": {name: list(own.brace_axes or ()) for name, own in braced.items()},
    }
    notes = {TASK_FRAMES_KEY: json.dumps(frames, sort_keys=True)} if ground_truth else {}
    notes[TASK_AXES_KEY] = json.dumps(axes, sort_keys=True)
    notes[INPUT_MODE_KEY] = str(given.input_mode)
    return notes


def read_command_limits(files: Sequence[str | Path]) -> dict[str, float]:
    """Each joint's |command| saturation in the simulator's input mode (motors.voltage_limit [V], or
    motors.torque_limit / the URDF's <limit effort> [N m or N]; 0: none) from these params files (later files
    win), by joint name. Raises ConfigError."""
    params: dict[str, Any] = {}
    for file in files:
        params.update(load_params_file(file, SIMULATOR))
    return command_limits_from_values(schema.read("simulator", params), [Path(f).resolve().parent for f in files])


def command_limits_from_values(values: schema.Values, search_dirs: Sequence[Path]) -> dict[str, float]:
    """``read_command_limits`` of the simulator's typed values (``schema.read``; a relative URDF looked up in
    ``search_dirs``). Raises ConfigError, OSError."""
    given = values.params
    names = list(given.robot.joint_names)
    if given.input_mode == "voltage":
        return dict.fromkeys(names, float(given.motors.voltage_limit))
    if given.motors.torque_limit_from_urdf:
        urdf = resolve_file(given.robot.urdf, "robot.urdf", search_dirs)
        try:
            joints = list(ET.parse(urdf).getroot().iter("joint"))
            efforts = {
                joint.get("name"): float(element.get("effort", 0.0))
                for joint in joints
                if (element := joint.find("limit")) is not None
            }
        except (ET.ParseError, ValueError) as exc:
            raise ConfigError(f"robot.urdf: no <limit effort> to read from {urdf}: {exc}") from None
        return {name: max(efforts.get(name, 0.0), 0.0) for name in names}
    limits = list(given.motors.torque_limit)
    return dict(zip(names, limits * len(names) if len(limits) == 1 else limits, strict=False))


def command_limits_from_json(text: str) -> dict[str, float]:
    """``COMMAND_LIMIT_KEY``'s document; {} where it is not {joint: number}."""
    try:
        document = json.loads(text)
    except ValueError:
        return {}
    if not isinstance(document, dict):
        return {}
    return {str(k): float(v) for k, v in document.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}


def task_axes_from_json(text: str) -> tuple[list[str] | None, dict[str, list[str]]]:
    """``TASK_AXES_KEY``'s document: the hand task's axes (None: not said) and each braced contact's;
    what is not a list of axes is left out (a bag written by something else)."""
    try:
        document = json.loads(text)
    except ValueError:
        return None, {}
    if not isinstance(document, dict):
        return None, {}
    braces = document.get("braces")
    own = {str(name): _axes(value) for name, value in (braces.items() if isinstance(braces, dict) else ())}
    return _axes(document.get(HAND)), {name: axes for name, axes in own.items() if axes is not None}


def _axes(value: Any) -> list[str] | None:
    ok = isinstance(value, list) and all(isinstance(axis, str) and axis in AXES for axis in value)
    return [str(axis) for axis in value] if ok else None


def task_frames_from_json(text: str) -> dict[str, Any]:
    try:
        document = json.loads(text)
    except ValueError:
        return {}
    return document if isinstance(document, dict) and isinstance(document.get(HAND), str) else {}


def is_ground_truth(topic: str) -> bool:
    return f"/{GROUND_TRUTH}" in f"/{topic.lstrip('/')}"


def true_positions(
    description: str, stamps: np.ndarray, names: Sequence[str], positions: np.ndarray, frames: Sequence[str]
) -> dict[int, np.ndarray]:
    """{stamp [ns]: (frames, 3)} world positions of ``frames`` at each true joint state."""
    import pinocchio as pin

    from bracing_core.kinematics import LinkPoses

    poses = LinkPoses(description)
    ids = [poses.robot.frame_id(frame) for frame in frames]
    out = {}
    for stamp, row in zip(stamps.tolist(), positions, strict=True):
        poses.update(poses.configuration(names, row))
        out[int(stamp)] = np.array([pin.updateFramePlacement(poses.model, poses.data, i).translation for i in ids])
    return out
