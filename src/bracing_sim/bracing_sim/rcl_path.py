"""The simulator's motor_commands waited for and taken and its state sent on rcl (``bracing_rcl.CommandPath``,
``StatePath``, C++): when the node takes that path, and what it does with each command taken.

A lockstep run on motor_command takes it, unless ``BRACING_SIMULATOR_PATH=python`` or the joints are more
than max_message_elements (the Python path refuses such a command by its size). Per message the C++ path
reads only one that needs no word said: the MotorCommand template's layout (the configured mode, the joints
by name in the simulator's order), every value finite and within its joint's limit (the engine's value rule,
``bracing_core.command_rule``, which the Python path applies too); its stamp and values go
to the stepping policy (``SimulatorStepper.offer``, which judges the stamp on both paths). Any other message
it hands to the node's Python path as its bytes, so each refusal and saturation is said by one
implementation (``bracing_ros.commands``). When a state is joint_states and /clock alone (``state_on_rcl``)
those two are written from their templates and published in C++ too (``bracing_rcl.StatePath``), and so are
the step's reports, contact_wrench/<name>, contacts and motor_state (``bracing_rcl.ReportPath``: the contact
set's names and frames and motor_state's lengths are fixed per run). The engine's step is one call on either
path (``bracing_core.simulator.Simulator.advance``: stepped, judged and taken back if refused, the GIL released).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerGuardCondition

from bracing_core.command_rule import command_api
from bracing_core.message_limits import MessageLimits
from bracing_core.typestore import CLOCK
from bracing_rcl import CommandPath, CommandStatus, Layout, ReportPath, StatePath
from bracing_ros import report_encoders, wire
from bracing_ros.cdr_template import PER_MESSAGE, derive_template
from bracing_ros.rcl_choice import python_only_reasons

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.publisher import Publisher
    from rclpy.subscription import Subscription

    from bracing_core.config import SimulatorConfig
    from bracing_core.node_log import NodeLog
    from bracing_core.stepping import SimulatorStepper
    from bracing_core.types import Vector

PATH_ENV = "BRACING_SIMULATOR_PATH"
"""The environment variable that chooses how the simulator takes motor_command: "rcl" (the default) or "python"."""
STATE_PATH_LINE = "state path: joint_states, /clock and the step's reports written in C++ on rcl"
"""What the node logs when ``state_on_rcl`` gives it a StatePath (and ``reports_on_rcl`` a ReportPath)."""


class CommandNode(Protocol):
    """What the C++ path uses of the simulator node (``bracing_sim.node.SimulatorNode``)."""

    config: SimulatorConfig
    core: SimulatorStepper
    limits: MessageLimits
    joint_names: list[str]
    command_reader: wire.MotorCommandDecoder

    @property
    def log(self) -> NodeLog: ...  # read-only: the node's is a NodeLog's subclass
    @property
    def context(self) -> Context: ...
    def on_command(self, data: bytes) -> None: ...
    def on_read_command(self, stamp_ns: int, command: Vector) -> None: ...


def python_only(config: SimulatorConfig, limits: MessageLimits, joints: int) -> str | None:
    """Why the run takes every motor_command on the Python path (None: the rcl path can take them)."""
    own = {
        f"command_source {config.command_source}": config.command_source != "motor_command",
        f"stepping {config.stepping}": config.stepping != "lockstep",
    }
    return python_only_reasons(PATH_ENV, own, limits, joints)


class RclCommands:
    """The node's motor_commands waited for and taken by ``bracing_rcl.CommandPath`` (see the module docstring)."""

    def __init__(self, node: CommandNode, command_sub: Subscription) -> None:
        self.node = node
        limit = np.broadcast_to(np.asarray(node.core.limit, dtype=float), (len(node.joint_names),))
        template = node.command_reader.template
        layout = Layout(*template.layout())
        self.interrupt = SignalHandlerGuardCondition(context=node.context)  # a stop signal ends a wait
        context: Any = node.context.handle  # rclpy's stubs know no pointer (its rcl_context_t*)
        handles = (command_sub.handle.pointer, context.pointer, self.interrupt.handle.pointer)
        self.path = CommandPath(command_api(), *handles, layout, limit.tolist())
        self.read = 0  # commands the C++ path read
        self.handed_over = 0  # commands it took and the Python path read

    def wait(self, timeout_s: float) -> bool:
        """Whether a motor_command came within ``timeout_s`` [s] (the wait in C++ on rcl, without the GIL)."""
        ready = self.path.wait(max(0, int(timeout_s * 1e9)))  # rcl_wait: a negative timeout blocks for good
        if not self.node.context.ok():
            raise ExternalShutdownException()
        return ready

    def line(self) -> str:
        """The log line of what each path did."""
        return f"motor_command path: {self.read} read in C++ on rcl, {self.handed_over} by the Python path"

    def take_queued(self) -> None:
        """Take every motor_command waiting, to the stepping policy (read here, or on the Python path)."""
        node = self.node
        while (taken := self.path.take()).status != CommandStatus.empty:
            if taken.status == CommandStatus.taken:
                self.read += 1
                node.on_read_command(taken.stamp_ns, np.array(taken.values))
            else:
                self.handed_over += 1
                node.on_command(taken.data or b"")


def commands_on_rcl(node: CommandNode, command_sub: Subscription) -> RclCommands | None:
    """The C++ path on rcl for motor_command, if the run can take it (``python_only``); which, logged."""
    reason = python_only(node.config, node.limits, len(node.joint_names))
    node.log.info(f"motor_command path: {'Python (' + reason + ')' if reason else 'C++ on rcl'}")
    return RclCommands(node, command_sub) if reason is None else None


class StateTopics(Protocol):
    """What the state path uses of the simulator's topics (``bracing_sim.topics.SimulatorTopics``)."""

    joint_pub: Publisher
    clock_pub: Publisher
    joint_wire: wire.JointStateEncoder
    truth_pubs: list[Publisher]
    link_pubs: list[Publisher]
    odom_pubs: list[Publisher]
    joint_command_pubs: list[Publisher]


def state_on_rcl(topics: StateTopics, config: SimulatorConfig, joints: int, keep_bytes: bool) -> StatePath | None:
    """joint_states and /clock published in C++ on rcl (their templates) when a state is those two alone (exact
    sensors, no collision geometry's links, no odom, not joint_commands) and motor_command is on rcl too;
    ``keep_bytes``: record_batch (the state's bytes into the batch)."""
    extra = topics.truth_pubs or topics.link_pubs or topics.odom_pubs or topics.joint_command_pubs
    if extra or python_only(config, MessageLimits.of(config), joints) is not None:
        return None
    joint = Layout(*topics.joint_wire.template.layout())
    clock = Layout(*derive_template(CLOCK, {"clock": PER_MESSAGE}).layout())
    return StatePath(topics.joint_pub.handle.pointer, topics.clock_pub.handle.pointer, joint, clock, keep_bytes)


class ReportTopics(Protocol):
    """What the report path uses of the simulator's topics (``bracing_sim.topics.SimulatorTopics``)."""

    wrench_pubs: list[Publisher]
    contacts_pub: Publisher
    motor_pub: Publisher
    wrench_wire: report_encoders.WrenchStampedEncoder
    contacts_wire: report_encoders.ContactsEncoder
    motor_wire: report_encoders.MotorStateEncoder


def reports_on_rcl(topics: ReportTopics, temperatures: int, keep_bytes: bool) -> ReportPath:
    """The step's reports (contact_wrench/<name>, contacts, motor_state) published in C++ on rcl from their
    encoders' templates, for a run whose state is (``state_on_rcl``); ``temperatures``: motor_state's (0 without
    the thermal model); ``keep_bytes``: as ``state_on_rcl``'s."""
    wrench, contacts = topics.wrench_wire.template(), topics.contacts_wire.template()
    motor = topics.motor_wire.template(temperatures)
    handles = [pub.handle.pointer for pub in topics.wrench_pubs]
    layouts = [Layout(*template.layout()) for template in (wrench, contacts, motor)]
    contacts_pub, motor_pub = topics.contacts_pub.handle.pointer, topics.motor_pub.handle.pointer
    return ReportPath(handles, contacts_pub, motor_pub, layouts[0], layouts[1], layouts[2], keep_bytes)
