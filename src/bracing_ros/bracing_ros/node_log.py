"""A node's ``bracing_core.node_log.NodeLog``: its rclpy logger, its rate-limited log, and run_status
for the warnings about the run (the recorder keeps them in the bag for the summary)."""

from __future__ import annotations

from rclpy.node import Node

from bracing_ros.rate_log import RateLimitedLog
from bracing_ros.status import StatusPublisher


class RosNodeLog:
    def __init__(self, node: Node, status: StatusPublisher, period: float) -> None:
        self._logger = node.get_logger()
        self._status = status
        self.limited = RateLimitedLog(node, period)  # (level, kind, message)

    def info(self, message: str) -> None:
        self._logger.info(message)

    def warning(self, message: str) -> None:
        self._logger.warning(message)

    def mark(self, kind: str) -> None:
        self.limited.mark(kind)

    def say(self, warnings: list[str], t: float) -> None:
        for warning in warnings:
            self._logger.warning(warning)
            self._status.warn(warning, t)
