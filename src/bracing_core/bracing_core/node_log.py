"""Where a node's policy speaks (no ROS): the ROS-free classes that decide what a node does
(``stepping``, ``answering``) say it through this interface; the node implements it with its
logger, its rate-limited log and run_status (``bracing_ros.node_log``), a test with lists."""

from __future__ import annotations

from typing import Protocol


class Refusal(ValueError):
    """Input a node refuses (a state, a command); ``kind`` (a word, no number) keys its rate-limited report."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


class NodeLog(Protocol):
    def info(self, message: str) -> None:
        """A line of the node's log."""

    def warning(self, message: str) -> None:
        """A warning in the node's log only (a configuration's, said once by its caller)."""

    def limited(self, level: str, kind: str, message: str) -> None:
        """A report of bad input or a repeated condition (``level`` error | warning | info): at most
        one per ``kind`` per log_throttle_period, with a count of those held back."""

    def mark(self, kind: str) -> None:
        """A report of ``kind`` was just said in full (``say``): the rate limit counts on from it."""

    def say(self, warnings: list[str], t: float) -> None:
        """Warnings about the run at sim time ``t`` [s]: in the log and on run_status, whence the
        recorder keeps them in the bag and the summary reads them."""
