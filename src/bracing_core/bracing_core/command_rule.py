"""The motor command's value rule, the one both of the simulator's command paths apply: every value finite, then
each saturated to its joint's limit (a limit not above zero: none) exactly as np.clip does. The engine holds it
(``bracing_engine.check_command``, command_api.h): the Python path (``bracing_ros.commands``) calls it through
``check_command``, the C++ path (``bracing_rcl.CommandPath``) through its C ABI (``command_api``). No ROS."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

import bracing_engine as engine
from bracing_core.types import Vector

if TYPE_CHECKING:
    from typing_extensions import CapsuleType


def check_command(values: Vector, limit: float | Vector) -> engine.CommandCheck:
    """``values`` (the joints' order) under the rule; ``limit``: one for every joint, or one per joint."""
    return engine.check_command(values, np.broadcast_to(np.asarray(limit, dtype=float), values.shape))


def command_api() -> CapsuleType:
    """The rule's C ABI (command_api.h): a capsule for bracing_rcl's CommandPath (the engine's table is static)."""
    return engine.command_api()
