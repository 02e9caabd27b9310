"""Flow control of reliable publishers: no message is dropped unacknowledged (``AckWindow``)."""

from __future__ import annotations

import time
from collections.abc import Sequence

from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.publisher import Publisher


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
