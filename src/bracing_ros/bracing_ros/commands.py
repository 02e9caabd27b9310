"""Validation of motor commands, independent of ROS message classes.

A command is accepted only if every configured joint appears exactly once by name,
every value is finite and the mode is the configured one. Over-limit values are
saturated, not rejected: both by the engine's value rule (``bracing_core.command_rule``), the one the
simulator's C++ path applies too. ``CommandError`` says what was wrong, quoting a few names at most. A
message larger than ``MessageLimits`` is refused before any work per element; every check is linear.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bracing_core.command_rule import check_command
from bracing_core.dynamics import InputMode
from bracing_core.message_limits import DEFAULT_LIMITS, MessageLimits, SizeError, duplicated, quote_names
from bracing_core.node_log import Refusal
from bracing_core.types import Vector
from bracing_core.typestore import motor_command_modes

MODE_CODES = {mode: motor_command_modes()[mode.value] for mode in InputMode}
"""An input mode -> its bracing_msgs/MotorCommand.mode constant."""


class CommandError(Refusal):
    """A command that must not be applied."""


def command_vector(
    names: Sequence[str],
    values: Sequence[float] | Vector,
    mode_code: int,
    joint_names: Sequence[str],
    mode: InputMode,
    limit: float | Vector = 0.0,
    limits: MessageLimits = DEFAULT_LIMITS,
) -> tuple[Vector, bool]:
    """The command in ``joint_names`` order, and whether it was saturated to ``limit`` (one value, or one per joint
    of ``joint_names``; 0 = none)."""
    expected_code = MODE_CODES[mode]
    if mode_code != expected_code:
        known = {v: k.value for k, v in MODE_CODES.items()}
        got = known.get(mode_code, f"unknown ({mode_code})")
        # Two kinds, whatever the value: another known mode, or a value no mode has (255 of them).
        kind = "mode" if mode_code in known else "mode-unknown"
        raise CommandError(kind, f"mode {got} but the simulator is configured for {mode.value} input")
    return _in_order(names, values, joint_names, "values", limit, limits)


def _in_order(
    names: Sequence[str],
    values: Sequence[float] | Vector,
    joint_names: Sequence[str],
    noun: str,
    limit: float | Vector,
    limits: MessageLimits,
) -> tuple[Vector, bool]:
    """``values`` named by ``names`` in ``joint_names`` order, checked finite and saturated to ``limit``
    (0 = none): the command and whether it was saturated. ``noun`` names the values in the errors."""
    try:
        limits.check_count("name", len(names))
        limits.check_count(noun, len(values))
    except SizeError as exc:
        raise CommandError(exc.kind, str(exc)) from None
    if len(names) != len(values):
        hint = " (an effort per joint is needed)" if noun == "efforts" else ""
        raise CommandError("length", f"{len(names)} names but {len(values)} {noun}{hint}")
    if list(names) == list(joint_names):  # the sender's order is ours: nothing to match
        u = np.array(values, dtype=float)
    else:
        u = _by_name(names, values, joint_names, limits)
    check = check_command(u, limit)  # the engine's value rule, the one the C++ path applies too
    if check.non_finite:
        bad = [joint_names[k] for k in check.non_finite]
        raise CommandError("non-finite", f"non-finite {noun} for {quote_names(bad)}")
    return check.values, check.saturated


def _by_name(
    names: Sequence[str], values: Sequence[float] | Vector, joint_names: Sequence[str], limits: MessageLimits
) -> Vector:
    """``values`` by ``names`` in ``joint_names`` order; names checked (each linear in the names)."""
    try:
        limits.check_name("name", max(names, key=len, default=""))
    except SizeError as exc:
        raise CommandError(exc.kind, str(exc)) from None
    if len(set(names)) != len(names):
        raise CommandError("duplicate", f"duplicate joint names {quote_names(duplicated(names))}")
    unknown = sorted(set(names) - set(joint_names))
    missing = sorted(set(joint_names) - set(names))
    if unknown or missing:
        raise CommandError(
            "unknown-names" if unknown else "missing-names",
            f"joint names do not match: unknown {quote_names(unknown)}, missing {quote_names(missing)}",
        )
    by_name = dict(zip(names, values, strict=True))
    return np.array([by_name[j] for j in joint_names], dtype=float)


def effort_vector(
    names: Sequence[str],
    efforts: Sequence[float] | Vector,
    joint_names: Sequence[str],
    limit: float | Vector = 0.0,
    limits: MessageLimits = DEFAULT_LIMITS,
) -> tuple[Vector, bool]:
    """A sensor_msgs/JointState command's efforts (ros2_control's JointStateTopicSystem: joints by
    name, the effort interface filled) in ``joint_names`` order, and whether they were saturated to
    ``limit`` (0 = none). CommandError names what is wrong: sizes, lengths, names, non-finite values."""
    return _in_order(names, efforts, joint_names, "efforts", limit, limits)
