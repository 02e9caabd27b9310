"""A node's log, rate-limited per kind of message."""

from __future__ import annotations

import time

from rclpy.node import Node

from bracing_core.message_limits import shorten

MAX_LINE_CHARACTERS = 1000
"""A report's characters at most (a longer one is cut, saying how long it was): the last line of
defence of a log's size, whatever a refusal quotes of the message it refuses."""


class RateLimitedLog:
    """At most one message per ``kind`` per ``period`` seconds, with a count of those held back, each
    at most MAX_LINE_CHARACTERS long. ``kind`` must be a word for the kind of report, never text with
    numbers from the message (each would be a kind of its own, with a rate limit of its own).

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
        text = shorten(message, MAX_LINE_CHARACTERS)
        if held:
            text += f" ({held} more like this since the last report)"
        if level == "error":
            self._logger.error(text)
        elif level == "warning":
            self._logger.warning(text)
        else:
            self._logger.info(text)

    def mark(self, kind: str) -> None:
        """A report of ``kind`` was just made elsewhere (said in full): the next waits its period, as after one."""
        self._last[kind] = time.monotonic()
