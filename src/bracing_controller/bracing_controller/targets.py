"""Targets while running, the ROS side: hand_target, hand_path, hand_pose_target and brace_target/<contact> in,
checked by ``bracing_core.targets.TaskTargets`` (the policy), the verdict out.

A flood costs bounded work: messages are taken raw (bytes, no decoding) and only the latest of each
topic is kept; it is decoded and checked once, when the next state is answered (``apply``), so at most
one target per topic per state (the latest wins, as a new target replaces the one before anyway). A
path's pose count and frame name length are read from its first bytes and checked before it is decoded.
What is accepted, if it changes the task's goal, is echoed on ``<topic>/accepted`` and logged; what is
refused goes out on ``<topic>/refused`` (its reason, kind and the count so far) with a warning, both
rate-limited per topic and kind (``RosNodeLog.limited``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

from bracing_core.kinematics import WORLD_FRAME
from bracing_core.node_log import NodeLog
from bracing_core.stamps import sec_nanosec, stamp_ns, stamp_seconds
from bracing_core.targets import (
    ACCEPTED,
    POSE_TOPIC,
    REFUSED,
    REFUSED_COUNT_KEY,
    REFUSED_KIND_KEY,
    Goal,
    TargetError,
    TaskTargets,
    echo_topic,
)
from bracing_core.types import HAND_TASK, TaskIndex, brace_task
from bracing_ros import wire
from bracing_ros.qos import ECHO_QOS, TARGET_QOS
from bracing_ros.raw_messages import deserialize, path_sizes


def _time(t_ns: int) -> Time:
    sec, nanosec = sec_nanosec(t_ns)
    return Time(sec=sec, nanosec=nanosec)


@dataclass
class TargetTopic:
    """One target topic: its task, its kind of message and where its verdicts go."""

    name: str  # hand_target, hand_path, hand_pose_target, brace_target/<contact>
    task: TaskIndex  # HAND_TASK or brace_task(j)
    msg_type: type  # geometry_msgs/PointStamped, nav_msgs/Path or geometry_msgs/PoseStamped
    accepted: Publisher
    refused: Publisher
    refusals: int = 0


class TargetTopics:
    """The subscriptions (``subscriptions``: the lockstep loop waits on them with its states) and the
    latest target of each topic, checked into ``targets`` by ``apply``."""

    def __init__(self, node: Node, targets: TaskTargets, contacts: list[str], log: NodeLog) -> None:
        self.node, self.targets, self.log = node, targets, log
        self.topics: dict[Subscription, TargetTopic] = {}
        self.pending: dict[str, tuple[TargetTopic, bytes]] = {}
        self._add("hand_target", HAND_TASK, PointStamped)
        self._add("hand_path", HAND_TASK, Path)
        self._add(POSE_TOPIC, HAND_TASK, PoseStamped)
        self.contacts = list(contacts)
        for j, name in enumerate(contacts):
            self._add(f"brace_target/{name}", brace_task(j), PointStamped)

    def retarget(self, targets: TaskTargets, contacts: list[str]) -> None:
        """A run built anew (per-run parameters): its ``targets``, and the brace topics of its ``contacts`` as a
        fresh process has them (another list: those of the run before destroyed, the new ones made, after the
        hand's); the hand's topics stay, each refusal count from zero."""
        self.targets = targets
        for topic in self.topics.values():
            topic.refusals = 0
        if contacts == self.contacts:
            return
        for subscription, topic in list(self.topics.items()):
            if topic.task != HAND_TASK:
                del self.topics[subscription]
                self.pending.pop(topic.name, None)
                self.node.destroy_subscription(subscription)
                self.node.destroy_publisher(topic.accepted)
                self.node.destroy_publisher(topic.refused)
        self.contacts = list(contacts)
        for j, name in enumerate(contacts):
            self._add(f"brace_target/{name}", brace_task(j), PointStamped)

    @property
    def subscriptions(self) -> list[Subscription]:
        return list(self.topics)

    def _add(self, name: str, task: TaskIndex, msg_type: type) -> None:
        node = self.node
        topic = TargetTopic(
            name,
            task,
            msg_type,
            node.create_publisher(msg_type, echo_topic(name, ACCEPTED), ECHO_QOS),
            node.create_publisher(DiagnosticStatus, echo_topic(name, REFUSED), ECHO_QOS),
        )

        def keep(data: bytes) -> None:  # the executor's callback (effort_forward; the lockstep loop's `take`)
            self.keep(topic, data)

        self.topics[node.create_subscription(msg_type, name, keep, TARGET_QOS, raw=True)] = topic

    def take(self, subscription: Subscription, data: bytes) -> None:
        """A target (CDR bytes) that came on ``subscription`` (the lockstep loop takes them with its states); none
        on a brace topic a run built anew no longer has (``retarget``)."""
        topic = self.topics.get(subscription)
        if topic is not None:
            self.keep(topic, data)

    def keep(self, topic: TargetTopic, data: bytes) -> None:
        self.pending[topic.name] = (topic, data)  # the latest wins

    def apply(self, now_ns: int) -> None:
        """Check the latest target of each topic that came since the last call, the state stamped ``now_ns``
        the first that would follow it (a path's stamps are checked against it), and say the verdict."""
        if not self.pending:  # the usual state: nothing came
            return
        pending, self.pending = self.pending, {}
        for topic, data in pending.values():
            try:
                goal, echo = self._goal(topic, data, now_ns)
            except TargetError as exc:
                self._refuse(topic, exc)
                continue
            if goal is None:  # the task's goal already: no change to say
                continue
            echo.header.stamp, echo.header.frame_id = _time(now_ns), WORLD_FRAME
            topic.accepted.publish(echo)
            self.log.limited("info", f"{topic.name} {ACCEPTED}", _accepted(topic, goal))

    def _goal(self, topic: TargetTopic, data: bytes, now_ns: int) -> tuple[Goal | None, Any]:
        """The target's goal (None: no change) and its echo, or TargetError."""
        if topic.msg_type is Path:
            return self._path(topic, data, now_ns)
        if topic.msg_type is PoseStamped:
            return self._pose(topic, data)
        return self._point(topic, data)

    def _pose(self, topic: TargetTopic, data: bytes) -> tuple[Goal | None, PoseStamped]:
        msg = _decoded(topic.name, data, PoseStamped)
        p, o = msg.pose.position, msg.pose.orientation
        goal = self.targets.pose([p.x, p.y, p.z], [o.x, o.y, o.z, o.w], msg.header.frame_id)
        if goal is not None:  # echoed as followed: the quaternion normalised
            norm = (o.x * o.x + o.y * o.y + o.z * o.z + o.w * o.w) ** 0.5
            o.x, o.y, o.z, o.w = o.x / norm, o.y / norm, o.z / norm, o.w / norm
        return goal, msg

    def _point(self, topic: TargetTopic, data: bytes) -> tuple[Goal | None, PointStamped]:
        msg = _decoded(topic.name, data, PointStamped)
        p = msg.point
        return self.targets.point(topic.task, [p.x, p.y, p.z], msg.header.frame_id), msg

    def _path(self, topic: TargetTopic, data: bytes, now_ns: int) -> tuple[Goal | None, Path]:
        try:
            sizes = path_sizes(data)
        except wire.DecodeError as exc:
            raise TargetError(f"{topic.name} refused: malformed ({exc})", "malformed") from None
        if sizes is not None:  # before any per-pose work (decoding included)
            frame_id_length, poses = sizes
            self.targets.check_size(topic.name, poses, frame_id_length)
        msg = _decoded(topic.name, data, Path)
        if sizes is None:  # an encapsulation path_sizes does not read: checked once decoded
            self.targets.check_size(topic.name, len(msg.poses), len(msg.header.frame_id))
        poses = msg.poses
        frames = [pose.header.frame_id or msg.header.frame_id for pose in poses]
        points = [[pose.pose.position.x, pose.pose.position.y, pose.pose.position.z] for pose in poses]
        times = [stamp_seconds(stamp_ns(pose.header.stamp)) for pose in poses]
        return self.targets.path(topic.task, times, points, frames, now_ns * 1e-9, topic.name), msg

    def _refuse(self, topic: TargetTopic, exc: TargetError) -> None:
        topic.refusals += 1
        self.log.limited("warning", f"{topic.name} {exc.kind}", str(exc))
        values = [
            KeyValue(key=REFUSED_KIND_KEY, value=exc.kind),
            KeyValue(key=REFUSED_COUNT_KEY, value=str(topic.refusals)),
        ]
        status = DiagnosticStatus(level=DiagnosticStatus.WARN, name=topic.name, message=str(exc), values=values)
        status.hardware_id = self.node.get_fully_qualified_name()
        topic.refused.publish(status)


def _decoded(name: str, data: bytes, msg_type: type) -> Any:
    """The target message of ``data``, or TargetError (kind malformed) for bytes rclpy cannot read."""
    try:
        return deserialize(data, msg_type)
    except wire.DecodeError as exc:
        raise TargetError(f"{name} refused: malformed ({str(exc)[:200]})", "malformed") from None


def _accepted(topic: TargetTopic, goal: Goal) -> str:
    """The log line of an accepted target."""
    if topic.msg_type is Path:
        return f"{topic.name}: {len(goal.times)} poses from t = {goal.times[0]:.3f} s to {goal.times[-1]:.3f} s"
    x, y, z = goal.points[0]
    turning = " and its orientation" if topic.msg_type is PoseStamped else ""
    return f"{topic.name}: moving to [{x:.4g}, {y:.4g}, {z:.4g}]{turning} and holding it"
