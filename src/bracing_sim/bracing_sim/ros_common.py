"""ROS plumbing shared by the nodes: parameters, stamps, QoS, the main() wrapper."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, cast

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from rcl_interfaces.msg import ParameterDescriptor
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerGuardCondition
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState

from bracing_msgs.msg import MotorCommand
from bracing_sim import wire
from bracing_sim.params import ConfigError

# Reliable and deep: a lockstep run must not lose a message to a slower recorder. Transient-local:
# a subscriber that discovers a publisher late (the recorder and the controller's first
# commands) still receives what was sent before the match.
STREAM_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=2000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# The nodes' own subscriptions are volatile: a node (re)started mid-run must answer the
# current state, not replay history. (A volatile subscription matches the publishers above.)
SUBSCRIBE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=2000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

EXIT_CONFIG = 2
EXIT_DIVERGED = 3


class RateLimitedLog:
    """At most one message per ``kind`` per ``period`` seconds, with a count of those held back.

    rclpy's throttle is per call site; one site reporting several kinds of bad input
    would hide all but the first kind.
    """

    def __init__(self, node: Node, period: float = 1.0) -> None:
        self._logger = node.get_logger()
        self._period = period
        self._last: dict[str, float] = {}
        self._held: dict[str, int] = {}

    def __call__(self, level: str, kind: str, message: str) -> None:
        now = time.monotonic()
        if now - self._last.get(kind, -1e18) < self._period:
            self._held[kind] = self._held.get(kind, 0) + 1
            return
        held = self._held.pop(kind, 0)
        self._last[kind] = now
        suffix = f" ({held} more like this since the last report)" if held else ""
        getattr(self._logger, level)(message + suffix)


class SubscriptionWaiter:
    """Waits on a few subscriptions with a wait set of their own and takes their messages.

    The hot loop of a lockstep node: an executor rebuilds its wait set (parameter services,
    timers, ...) on every spin, which costs more than a whole simulation step; this waits
    on the subscriptions that matter (and on Ctrl-C). Call the executor now and then so
    that the node's services still answer.
    """

    def __init__(self, node: Node, subscriptions: Subscription | Sequence[Subscription]) -> None:
        self._subscriptions = [subscriptions] if isinstance(subscriptions, Subscription) else list(subscriptions)
        self._context = node.context
        self._wait_set = _rclpy.WaitSet(len(self._subscriptions), 1, 0, 0, 0, 0, node.context.handle)
        self._interrupt = SignalHandlerGuardCondition(context=node.context)

    def take(self, timeout_sec: float) -> list[Any]:
        """Every message available now (of the first subscription), waiting up to ``timeout_sec``."""
        return [message for _, message in self.take_all(timeout_sec)]

    def take_all(self, timeout_sec: float) -> list[tuple[Subscription, Any]]:
        """(subscription, message) for every message available now, waiting up to ``timeout_sec``."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for subscription in self._subscriptions:
            wait_set.add_subscription(subscription.handle)
        wait_set.add_guard_condition(self._interrupt.handle)
        wait_set.wait(int(timeout_sec * 1e9))
        if not self._context.ok():
            raise ExternalShutdownException()
        ready = wait_set.get_ready_entities("subscription")
        return self._take_ready([sub for sub in self._subscriptions if sub.handle.pointer in ready])

    @staticmethod
    def _take_ready(subscriptions: list[Subscription]) -> list[tuple[Subscription, Any]]:
        messages = []
        for subscription in subscriptions:
            handle = subscription.handle
            while (taken := handle.take_message(subscription.msg_type, subscription.raw)) is not None:
                messages.append((subscription, taken[0]))
        return messages


def read_joint_state(data: bytes, decoder: wire.JointStateDecoder) -> wire.JointStateData:
    """A JointState taken raw (CDR bytes); rclpy decodes encapsulations ``wire`` does not read.

    Raises ``wire.DecodeError`` for bytes that are not a JointState.
    """
    try:
        return decoder.decode(data)
    except wire.UnsupportedEncoding:
        msg = _deserialize(data, JointState)
        return wire.JointStateData(
            nanoseconds(msg.header.stamp),
            list(msg.name),
            np.array(msg.position, dtype=float),
            np.array(msg.velocity, dtype=float),
            np.array(msg.effort, dtype=float),
        )


def read_motor_command(data: bytes, decoder: wire.MotorCommandDecoder) -> wire.MotorCommandData:
    """A MotorCommand taken raw (CDR bytes); see :func:`read_joint_state`."""
    try:
        return decoder.decode(data)
    except wire.UnsupportedEncoding:
        msg = _deserialize(data, MotorCommand)
        return wire.MotorCommandData(
            nanoseconds(msg.header.stamp), int(msg.mode), list(msg.name), np.array(msg.value, dtype=float)
        )


def _deserialize(data: bytes, msg_type: type) -> Any:
    try:
        return deserialize_message(data, msg_type)
    except Exception as exc:  # rclpy raises its RMWError (and others) for bytes it cannot read
        raise wire.DecodeError(str(exc).split(", at /")[0]) from None


def read_parameters(node: Node) -> dict[str, Any]:
    """Declare every parameter the node was given and return them all as a flat dict.

    Declared with dynamic typing so that ``offset: 0`` (an integer) or ``target: []``
    (NOT_SET to rcl) reach the configuration layer, which validates types and names in
    one place, with messages naming the parameter.
    """
    dynamic = ParameterDescriptor(dynamic_typing=True)
    for name, parameter in node._parameter_overrides.items():  # rclpy keeps --ros-args overrides here
        if not node.has_parameter(name):
            node.declare_parameter(name, parameter.value, dynamic)
    # get_parameters_by_prefix returns Parameter objects (its annotation says values).
    parameters = cast(dict[str, Parameter], node.get_parameters_by_prefix(""))
    return {name: parameter.value for name, parameter in parameters.items()}


def nanoseconds(time: Time) -> int:
    return int(time.sec) * 1_000_000_000 + int(time.nanosec)


def run(node_factory: Callable[[], Node], spin: Callable[[Node], int], args: list[str] | None = None) -> int:
    """Create the node, spin it, and turn start-up errors into one clear line and exit 2."""
    code = 0
    node: Node | None = None
    try:
        try:
            rclpy.init(args=args if args is not None else sys.argv)
        except RCLError as exc:  # e.g. a params file rcl cannot parse
            raise ConfigError(str(exc).split(", at /")[0]) from None
        node = node_factory()
        code = spin(node)
    except (ConfigError, ParameterException) as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        code = EXIT_CONFIG
    except KeyboardInterrupt:
        code = 0
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    return code
