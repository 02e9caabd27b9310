"""The nodes' per-state paths on rcl's C API (C++, ``_rcl``). ``ControllerPath`` waits for a joint_states on an
rclpy subscription's rcl handle and takes it, checks it, runs the engine's law (``bracing_engine.law_api``: the
check and the law are the engine's, one implementation for both of the node's paths), and publishes the
motor_command and then the controller_state on rclpy publishers' rcl handles, with the GIL released, state after
state until one needs Python (``Served``). What it does not answer itself goes back to the node's Python path as
bytes (``Status.python``). ``CommandPath`` waits for and takes the simulator's motor_commands likewise: read in C++
when they need no word said (the engine's value rule, ``bracing_core.command_rule``, the one the Python path applies),
else their bytes for the simulator's Python path (``CommandStatus.python``); ``StatePath`` publishes its
joint_states and /clock, ``ReportPath`` a step's reports (contact_wrench/<name>, contacts, motor_state)."""

import rclpy  # noqa: F401  first: it loads the rcl and rmw libraries this module links

from bracing_rcl._rcl import (
    CommandPath,
    CommandStatus,
    CommandTake,
    ControllerPath,
    Layout,
    Outcome,
    ReportPath,
    ReportsSent,
    Served,
    StatePath,
    StateSent,
    Status,
)

__all__ = [
    "CommandPath",
    "CommandStatus",
    "CommandTake",
    "ControllerPath",
    "Layout",
    "Outcome",
    "ReportPath",
    "ReportsSent",
    "Served",
    "StatePath",
    "StateSent",
    "Status",
]
