"""ROS plumbing shared by the nodes: parameters, stamps, QoS, the main() wrapper."""

from __future__ import annotations

import faulthandler
import signal
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerGuardCondition, SignalHandlerOptions
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState

from bracing_core import rcl_yaml
from bracing_core.params import ConfigError
from bracing_msgs.msg import MotorCommand
from bracing_ros import wire
from bracing_ros.fastdds import use_fastdds_profile as use_fastdds_profile  # re-exported: the profiles live there
from bracing_ros.lifetime import stop_with_parent

# Reliable, transient-local and deep: a subscriber that discovers a publisher late (the recorder
# on a busy machine) still receives what was sent before the match. A KEEP_LAST writer drops its
# oldest sample when the history is full, acknowledged or not; AckWindow (every depth / 2
# messages) makes sure no unacknowledged sample is ever that old.
STREAM_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10000,
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
    would hide all but the first kind. rclpy also fixes a call site's severity at its
    first call (a second severity raises ValueError), so each severity is logged from a
    line of its own below.
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
        text = message + (f" ({held} more like this since the last report)" if held else "")
        if level == "error":
            self._logger.error(text)
        elif level == "warning":
            self._logger.warning(text)
        else:
            self._logger.info(text)

    def mark(self, kind: str) -> None:
        """A report of ``kind`` was just made elsewhere (said in full): the next waits its period, as after one."""
        self._last[kind] = time.monotonic()


def create_waking_publisher(node: Node, msg_type: type, topic: str, qos: QoSProfile) -> Publisher:
    """``node.create_publisher``, for a publisher whose matches ``wait_until`` waits for: a match
    wakes the executor at once (the callback itself has nothing to do; ``wait_until`` checks)."""
    return node.create_publisher(msg_type, topic, qos, event_callbacks=PublisherEventCallbacks(matched=_matched))


def _matched(_: object) -> None:
    pass


def wait_until(node: Node, executor: Executor, ready: Callable[[], bool], message: str) -> None:
    """Serve ``executor`` until ``ready()`` (a subscription count, say), logging ``message`` (what
    it waits for) once it has waited 2 s. Discovery and matching happen in DDS's own threads; a
    publisher made with ``create_waking_publisher`` ends the executor's wait when it matches."""
    since, told = time.monotonic(), False
    while not ready():
        executor.spin_once(timeout_sec=0.05)
        if not told and time.monotonic() - since > 2.0:
            told = True
            node.get_logger().info(message)


class AckWindow:
    """Flow control for reliable publishers whose subscribers must not lose a message.

    A KEEP_LAST writer drops its oldest sample when its history is full, acknowledged or
    not: a subscriber that matches late (discovery on a busy machine) or falls behind (a
    niced recorder) would lose the first or oldest messages. Every ``window`` messages
    (half the history depth), wait until every matched subscriber has acknowledged
    everything sent, so no more than ``window`` are ever unacknowledged and the history
    never overflows. (Each wait costs up to a heartbeat period, 50 ms: a wider window
    waits less often.)
    """

    def __init__(self, node: Node, publishers: Sequence[Publisher], depth: int) -> None:
        self._node = node
        self._publishers = list(publishers)
        self.window = max(depth // 2, 1)
        self._sent = 0

    def sent(self) -> None:
        """One more message sent on each publisher; waits for acknowledgements every ``window``."""
        self._sent += 1
        if self._sent >= self.window:
            self._sent = 0
            self.wait()

    def wait(self, timeout_sec: float | None = None) -> bool:
        """Until everything sent is acknowledged (or ``timeout_sec``); says what it waits for."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        told = time.monotonic() + 5.0
        for publisher in self._publishers:
            while not publisher.wait_for_all_acked(Duration(seconds=0.5)):
                if not self._node.context.ok():
                    raise ExternalShutdownException()
                now = time.monotonic()
                if deadline is not None and now >= deadline:
                    return False
                if now >= told:
                    told = now + 5.0
                    self._node.get_logger().info(
                        f"waiting for the subscribers of {publisher.topic_name} to acknowledge (a slow recorder?)"
                    )
        return True


class SubscriptionWaiter:
    """Waits on a few subscriptions with a wait set of their own and takes their messages.

    The hot loop of a lockstep node: an executor rebuilds its wait set (parameter services,
    timers, ...) on every spin, which costs more than a whole simulation step; this waits
    on the subscriptions that matter (and on Ctrl-C). Call the executor now and then so
    that the node's services still answer.

    rclpy has no public wait set: this class is the project's one use of its internal one
    (``_rclpy.WaitSet``, what rclpy's own executors wait on).
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
        return wire.joint_state_data(_deserialize(data, JointState))


def read_motor_command(data: bytes, decoder: wire.MotorCommandDecoder) -> wire.MotorCommandData:
    """A MotorCommand taken raw (CDR bytes); see :func:`read_joint_state`."""
    try:
        return decoder.decode(data)
    except wire.UnsupportedEncoding:
        return wire.motor_command_data(_deserialize(data, MotorCommand))


def _deserialize(data: bytes, msg_type: type) -> Any:
    try:
        return deserialize_message(data, msg_type)
    except Exception as exc:  # rclpy raises its RMWError (and others) for bytes it cannot read
        raise wire.DecodeError(str(exc).split(", at /")[0]) from None


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt()


def run(node_factory: Callable[[], Node], spin: Callable[[Node], int], args: list[str] | None = None) -> int:
    """Create the node, spin it, and turn start-up errors into one clear line and exit 2."""
    faulthandler.enable()  # a crash in native code (DDS, pinocchio) leaves its Python stack in the node's log
    code = 0
    node: Node | None = None
    try:
        try:
            # Python's own SIGINT handling (KeyboardInterrupt) instead of rclpy's, which shuts the
            # context down at once: a node stopping must still flush what its subscribers have
            # not acknowledged (see AckWindow), and that needs a live context. SIGTERM alike.
            signal.signal(signal.SIGTERM, _interrupt)
            # Even when started with SIGINT ignored (a background job of a script, nohup): bracing-pair
            # stops the nodes with it. Seen: the controller of a backgrounded make bench ignored it.
            signal.signal(signal.SIGINT, signal.default_int_handler)
            stop_with_parent()
            use_fastdds_profile()
            rclpy.init(args=args if args is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
        except RCLError as exc:  # e.g. a params file rcl cannot parse: say which parameter, and the fix
            argv = args if args is not None else sys.argv
            raise ConfigError(rcl_yaml.explain(argv) or str(exc).split(", at /")[0]) from None
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
