"""Waiting for subscribers to match a node's publishers (discovery), woken at once by a match."""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.event_handler import PublisherEventCallbacks
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile


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
