"""Targets while running, the ROS side: hand_target, hand_path and brace_target/<contact> in, a
checked goal out to ``bracing_core.targets.TaskTargets`` (the policy), a warning for each refused one."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from bracing_core.targets import TargetError, TaskTargets

TARGET_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""What a script, RViz or MoveIt publishes by default (reliable); a transient-local publisher matches it too."""


def _seconds(stamp: object) -> float:
    return int(stamp.sec) + int(stamp.nanosec) * 1e-9  # type: ignore[attr-defined]


class TargetTopics:
    """The subscriptions; ``targets`` holds what was accepted (the node feeds it to the law)."""

    def __init__(self, node: Node, targets: TaskTargets, contacts: list[str]) -> None:
        self.node = node
        self.targets = targets
        self.handlers: dict[Subscription, Callable[[Any], None]] = {}
        self._add(PointStamped, "hand_target", lambda m: self.on_point(0, m))
        self._add(Path, "hand_path", self.on_path)
        for j, name in enumerate(contacts):
            self._add(PointStamped, f"brace_target/{name}", partial(self.on_point, j + 1))

    def _add(self, msg_type: type, topic: str, handler: Callable[[Any], None]) -> None:
        self.handlers[self.node.create_subscription(msg_type, topic, handler, TARGET_QOS)] = handler

    def take(self, subscription: Subscription, msg: Any) -> None:
        """A target that came on ``subscription`` (the lockstep loop waits on them with its states)."""
        self.handlers[subscription](msg)

    def on_point(self, task: int, msg: PointStamped) -> None:
        p = msg.point
        try:
            self.targets.point(task, [p.x, p.y, p.z], msg.header.frame_id)
        except TargetError as exc:
            self.node.get_logger().warning(str(exc))
            return
        what = self.targets.tasks[task].what
        self.node.get_logger().info(f"{what}: moving to [{p.x:.4g}, {p.y:.4g}, {p.z:.4g}] and holding it")

    def on_path(self, msg: Path) -> None:
        poses = list(msg.poses)
        frames = [pose.header.frame_id or msg.header.frame_id for pose in poses]
        points = [[pose.pose.position.x, pose.pose.position.y, pose.pose.position.z] for pose in poses]
        times = [_seconds(pose.header.stamp) for pose in poses]
        try:
            self.targets.path(0, times, points, frames)
        except TargetError as exc:
            self.node.get_logger().warning(str(exc).replace("hand_target", "hand_path", 1))
            return
        self.node.get_logger().info(f"hand_path: {len(poses)} poses from t = {times[0]:.3f} s to {times[-1]:.3f} s")
