"""The topics of a recorded run and what a complete lockstep bag holds (no rclpy needed).

The recorder subscribes to ``recorded_topics``; the pair checks a finished bag's message
counts (read once, with the rest of the report) against ``expected_counts``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from bracing_core.contact_roles import LINK_PENETRATION_TOPIC
from bracing_core.mobile_base import CMD_VEL_TOPIC, ODOM_TOPIC
from bracing_core.overrides import CONTROLLER
from bracing_core.sensing import GROUND_TRUTH
from bracing_core.targets import ACCEPTED, ORIENTATION_ERROR_TOPIC, POSE_TOPIC, REFUSED, echo_topic
from bracing_core.typestore import (
    CLOCK,
    CONTACTS,
    CONTROLLER_STATE,
    DIAGNOSTIC_STATUS,
    JOINT_STATE,
    MARKER_ARRAY,
    MOTOR_COMMAND,
    MOTOR_STATE,
    ODOMETRY,
    PATH,
    POINT_STAMPED,
    POSE_STAMPED,
    TF_MESSAGE,
    TWIST_STAMPED,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)

DESCRIPTION_TOPIC = "robot_description"
PARAMETER_EVENTS_TOPIC = "/parameter_events"
"""rclpy's parameter events: the recorder keeps the controller's changes (as many as there are)."""
CONTROLLER_NODE = CONTROLLER


def target_topics(contacts: Sequence[str]) -> list[tuple[str, str]]:
    """(relative topic, ROS 2 type name) of the controller's targets while running: sent by anyone at any
    time on volatile publishers, recorded as they come (a run without any has none of these topics)."""
    return [
        ("hand_target", POINT_STAMPED),
        ("hand_path", PATH),
        (POSE_TOPIC, POSE_STAMPED),
        *((f"brace_target/{name}", POINT_STAMPED) for name in contacts),
    ]


def target_verdict_topics(contacts: Sequence[str]) -> list[tuple[str, str]]:
    """(relative topic, ROS 2 type name) of what the controller made of each target it took:
    ``<target>/accepted`` (as it follows it, once per change) and ``<target>/refused`` (why)."""
    out = []
    for topic, type_name in target_topics(contacts):
        out += [(echo_topic(topic, ACCEPTED), type_name), (echo_topic(topic, REFUSED), DIAGNOSTIC_STATUS)]
    return out


OPTIONAL_STATE_TOPICS = [
    (ORIENTATION_ERROR_TOPIC, VECTOR3_STAMPED),
    (LINK_PENETRATION_TOPIC, CONTACTS),
    (ODOM_TOPIC, ODOMETRY),
]
"""(relative topic, ROS 2 type name) of what the nodes publish once per state only in some configurations
(hand_orientation_error: the controller, with an orientation task; link_penetration: the simulator, with
robot.collision_geometry; odom: the simulator, with a mobile base): recorded from the first message, at its
header stamp, one by one or in record_batch; a run without it has no such topic (no count expected)."""

COMMAND_TOPICS = [(CMD_VEL_TOPIC, TWIST_STAMPED)]
"""(relative topic, ROS 2 type name) of what a teleop or navigation stack sends the controller at any time
(cmd_vel: base_command cmd_vel): recorded as they come, as the targets; a run without any has no such topic."""

RECORDER_NODE = "bracing_recorder"

SCENE_TOPICS = {
    "tf": ("/tf", TF_MESSAGE),
    "tf_static": ("/tf_static", TF_MESSAGE),
    "contact_markers": ("contact_markers", MARKER_ARRAY),
}
"""Topics the recorder derives (``scene.Derived.key`` -> topic, type)."""


def recorded_topics(contacts: Sequence[str], ground_truth: bool = False) -> list[tuple[str, str]]:
    """(relative topic, ROS 2 type name) of every topic the nodes publish once per state; ``ground_truth``:
    with the truth the simulator publishes beside what its sensors measure (sensors.* not exact)."""
    truth = [(GROUND_TRUTH + "joint_states", JOINT_STATE), (GROUND_TRUTH + "motor_state", MOTOR_STATE)]
    return [
        *(truth if ground_truth else []),
        ("joint_states", JOINT_STATE),
        *((f"contact_wrench/{name}", WRENCH_STAMPED) for name in contacts),
        ("contacts", CONTACTS),
        ("motor_state", MOTOR_STATE),
        ("/clock", CLOCK),
        ("motor_command", MOTOR_COMMAND),
        ("controller_state", CONTROLLER_STATE),
    ]


def expected_counts(
    contacts: Sequence[str], expected: int, namespace: str = "", ground_truth: bool = False
) -> dict[str, int]:
    """Messages a complete lockstep bag of ``expected`` states holds, per resolved topic name.

    Every topic is sent once per state in lockstep (the command and controller state once
    per state answered), so a bag of N steps holds N + 1 of each, and as many ``/tf`` and
    ``contact_markers``; ``robot_description`` and ``/tf_static`` once.
    """
    prefix = "/" + namespace.strip("/") + "/" if namespace.strip("/") else "/"

    def resolve(topic: str) -> str:
        return topic if topic.startswith("/") else prefix + topic

    counts = {resolve(topic): expected for topic, _ in recorded_topics(contacts, ground_truth)}
    counts[resolve(DESCRIPTION_TOPIC)] = 1
    counts[resolve(SCENE_TOPICS["tf_static"][0])] = 1
    counts[resolve(SCENE_TOPICS["tf"][0])] = expected
    if contacts:
        counts[resolve(SCENE_TOPICS["contact_markers"][0])] = expected
    return counts


def missing_from_counts(
    counts: Mapping[str, int], contacts: Sequence[str], expected: int, namespace: str = "", ground_truth: bool = False
) -> list[str]:
    """One line per topic of ``counts`` (messages per topic in a bag) recorded fewer times than a
    complete lockstep bag of ``expected`` states holds."""
    return [
        f"{name}: {counts.get(name, 0)} of {wanted} messages"
        for name, wanted in expected_counts(contacts, expected, namespace, ground_truth).items()
        if counts.get(name, 0) < wanted
    ]
