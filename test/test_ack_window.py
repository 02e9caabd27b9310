"""AckWindow's flow control without DDS: when its blocking wait (up to a heartbeat period, the lockstep loop
stalled meanwhile) happens, and when a check before a send ends the window early instead."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from rclpy.duration import Duration

from bracing_ros.ack_window import AckWindow


class _Publisher:
    """A reliable publisher whose subscribers acknowledge at heartbeats: a check without waiting sees
    ``acked_now``; a blocking wait always ends acknowledged (a heartbeat came). Records each wait's timeout [ns]."""

    def __init__(self, acked_now: bool) -> None:
        self.acked_now = acked_now
        self.timeouts_ns: list[int] = []

    def wait_for_all_acked(self, timeout: Duration) -> bool:
        self.timeouts_ns.append(timeout.nanoseconds)
        return self.acked_now or timeout.nanoseconds > 0


def _window(publisher: _Publisher, depth: int) -> AckWindow:
    node: Any = SimpleNamespace(context=SimpleNamespace(ok=lambda: True))
    return AckWindow(node, [publisher], depth)  # type: ignore[list-item]


def test_a_window_acknowledged_before_its_end_needs_no_blocking_wait() -> None:
    publisher = _Publisher(acked_now=True)
    flow = _window(publisher, depth=4)  # a wait every 2 messages
    flow.confirm()  # nothing sent yet: nothing to check
    for _ in range(5):
        flow.confirm()  # before each send after the first: what was sent is acknowledged
        flow.sent()
    assert publisher.timeouts_ns == [0, 0, 0, 0]  # four checks, never a blocking wait
    assert flow.acked_count == 4  # the last confirm saw the first four acknowledged


def test_a_window_not_acknowledged_by_its_end_still_waits() -> None:
    publisher = _Publisher(acked_now=False)
    flow = _window(publisher, depth=4)
    for _ in range(2):
        flow.confirm()
        flow.sent()
    assert publisher.timeouts_ns == [0, Duration(seconds=0.5).nanoseconds]  # a failed check, then the wait
    assert flow.acked_count == 2
