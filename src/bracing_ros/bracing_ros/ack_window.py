"""Flow control of reliable publishers: no message is dropped unacknowledged (``AckWindow``)."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence

from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.publisher import Publisher

LEASE_NOTE = "a subscriber killed stays matched until its DDS lease ends, ~20 s"


class AckWindow:
    """Flow control for reliable publishers whose subscribers must not lose a message.

    A KEEP_LAST writer drops its oldest sample when its history is full, acknowledged or
    not: a subscriber that matches late (discovery on a busy machine) or falls behind (a
    niced recorder) would lose the first or oldest messages. Every ``window`` messages
    (half the history depth), wait until every matched subscriber has acknowledged
    everything sent, so no more than ``window`` are ever unacknowledged and the history
    never overflows. (Each wait costs up to a heartbeat period, 50 ms: a wider window
    waits less often, and ``confirm`` before a send ends a window acknowledged meanwhile
    without any wait.)
    """

    def __init__(self, node: Node, publishers: Sequence[Publisher], depth: int) -> None:
        self._node = node
        self._publishers = list(publishers)
        self.window = max(depth // 2, 1)
        self._sent = 0
        self.sent_count = 0  # messages sent on each publisher
        self.acked_count = 0  # of those, how many every subscriber had acknowledged at the last wait or confirm

    def sent(self) -> None:
        """One more message sent on each publisher; waits for acknowledgements every ``window``."""
        self.sent_count += 1
        self._sent += 1
        if self._sent >= self.window:
            self._sent = 0
            self.wait()

    def confirm(self) -> None:
        """Without waiting: if every subscriber has acknowledged everything sent so far, the window starts
        afresh, so its end needs no wait. Call it before sending: what was just sent is acknowledged only at
        the next heartbeat, so a check after it never passes; one before it sees the acknowledgements that
        came since the last message (record_batch: a batch every ~25 ms, heartbeats every 50 ms)."""
        if self._sent and all(publisher.wait_for_all_acked(Duration(seconds=0)) for publisher in self._publishers):
            self._sent = 0
            self.acked_count = self.sent_count

    def wait(self, timeout_sec: float | None = None) -> bool:
        """Until everything sent is acknowledged (or ``timeout_sec``); says what it waits for."""
        sent = self.sent_count
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
        self.acked_count = sent
        return True

    def close(self, timeout_sec: float) -> list[tuple[str, str]]:
        """At the node's stop: until every subscriber has acknowledged everything sent, at most
        ``timeout_sec`` in all; what did not happen, as (level, line) for the log (none: all of it did).

        A subscriber that leaves meanwhile (it stopped, or DDS declared it gone) is not waited for,
        and is named: its node had nothing more to be flushed to.
        """
        deadline = time.monotonic() + timeout_sec
        sent, lines = self.sent_count, []
        for publisher in self._publishers:
            topic, since = publisher.topic_name, f"the messages after the {self.acked_count}th of {sent}"
            before = self._subscribers(topic)
            acked, waited = self._wait_one(publisher, deadline)
            left = before - self._subscribers(topic)
            if waited and left:
                names = ", ".join(sorted(left.elements()))
                lines.append(("warning", f"{topic}: {names} left before acknowledging {since}: nothing to flush to it"))
            if not acked:
                names = ", ".join(sorted(self._subscribers(topic).elements())) or "none"
                lines.append((
                    "error",
                    f"{topic}: not every subscriber ({names}) acknowledged {since} within {timeout_sec:g} s: "
                    f"lost to whichever has not ({LEASE_NOTE})",
                ))  # fmt: skip
        if not lines:
            self.acked_count = sent
        return lines

    def _wait_one(self, publisher: Publisher, deadline: float) -> tuple[bool, bool]:
        """(acknowledged by every subscriber still matched, whether that needed a wait) by ``deadline``."""
        waited = False
        while not publisher.wait_for_all_acked(Duration(seconds=0.5)):
            waited = True
            if not self._node.context.ok():
                raise ExternalShutdownException()
            if time.monotonic() >= deadline:
                return False, waited
        return True, waited

    def _subscribers(self, topic: str) -> Counter[str]:
        """The nodes subscribed to ``topic`` (by name, as many times as they subscribe)."""
        return Counter(info.node_name for info in self._node.get_subscriptions_info_by_topic(topic))
