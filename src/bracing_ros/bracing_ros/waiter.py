"""The lockstep nodes' wait on a few subscriptions: a wait set of their own (rclpy's private one)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerGuardCondition
from rclpy.subscription import Subscription

from bracing_ros.stop_signal import taking


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
        return self.take_ready(self.wait(timeout_sec))

    def wait(self, timeout_sec: float) -> list[Subscription]:
        """The subscriptions with a message now, waiting up to ``timeout_sec`` (nothing taken: ``take_ready``)."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for subscription in self._subscriptions:
            wait_set.add_subscription(subscription.handle)
        wait_set.add_guard_condition(self._interrupt.handle)
        wait_set.wait(int(timeout_sec * 1e9))
        if not self._context.ok():
            raise ExternalShutdownException()
        ready = wait_set.get_ready_entities("subscription")
        return [sub for sub in self._subscriptions if sub.handle.pointer in ready]

    @staticmethod
    def take_ready(subscriptions: list[Subscription]) -> list[tuple[Subscription, Any]]:
        """(subscription, message) for every message of ``subscriptions`` available now."""
        messages = []
        for subscription in subscriptions:
            handle = subscription.handle
            take = partial(handle.take_message, subscription.msg_type, subscription.raw)
            while (taken := taking(take)) is not None:
                messages.append((subscription, taken[0]))
        return messages
