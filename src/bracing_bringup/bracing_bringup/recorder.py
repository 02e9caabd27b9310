"""Record every topic of the bracing interface to a rosbag2 bag (mcap storage).

Usage::

    python -m bracing_bringup.recorder --output DIR/bag [--namespace NS] \
        [--contacts elbow,...] [--params-file FILE ...] [--scenario NAME] [--ros-args ...]

The bag embeds the message definitions (bracing_msgs included), so any rosbag2 reader
decodes it. Messages are received already serialised (CDR, ``raw=True``) and written as
they are; the bag timestamp of a message is its header stamp (``clock`` for ``/clock``,
0 for ``robot_description``).

So that a viewer can draw the run, the recorder also writes what it derives from the
recorded messages (``bracing_bringup.scene``): ``/tf_static`` once and ``/tf`` per
``joint_states`` (every link's pose, pinocchio kinematics of the URDF received on
``robot_description``), and ``contact_markers`` per state (surface, contact point, force
arrow from ``contact_wrench/<name>``). It derives them when idle and on stop (after the
drain), so a lockstep run is not slowed; ``--no-scene`` leaves them out. ``--params-file`` names the
params files the nodes run with (as many as they got, in order): the bag's metadata then holds the
contact surfaces (``surfaces``) and the world axes of the controller's tasks (``truth.TASK_AXES_KEY``: the
report plots each) and the controller's input mode (``truth.INPUT_MODE_KEY``: the report's for a bag without
motor_command), and the markers draw a sphere or a cylinder as one. ``--scenario``
names the scenario in the bag's metadata (default: the first params file's name), for the report.
The metadata is written when the bag closes: a recorder killed before leaves its bag cut short, which
``bracing_analysis.bag_recovery`` rewrites whole (``bag_notes`` gives its metadata again).

The targets sent to the controller while it runs (``hand_target``, ``hand_path``,
``brace_target/<contact>``) are recorded as they come, at the sim time of the last ``/clock`` recorded
before each (their own stamps are the sender's); a run without any has none of these topics. So is
what the controller made of them (``<target>/accepted``, ``<target>/refused``): the report draws the
accepted ones only and counts the refused ones. The controller's ``hand_orientation_error`` (only with an
orientation task) is recorded at its stamps, from its first message.

The controller's parameter changes while it runs (``ros2 param set``) are recorded from rclpy's
``/parameter_events``: the events of the run's controller that change a value, stamped by it with the
sim time of the last state it answered with the old values (see bracing_controller.node).

The run's warnings are recorded from ``run_status``: its WARNING messages (what the simulator warns
about, also in its log), stamped with their sim time; the topic is in the bag from the first warning
(a run without any has none), and the summary reads them there. With ``--expect-states`` the bag is
closed once every topic has its messages and, if a simulator speaks on run_status, once it has said
FINISHED (after its last warning: one writer, in order).

With ``--from-batches`` the per-state topics come in ``bracing_msgs/RecordBatch`` samples on
``record_batch`` (the nodes' ``record_batch`` parameter; bracing-pair sets both): each message is
written under its own topic, exactly as if it had come on it, without one DDS delivery per message
(``bracing_core.record_batch`` says why). A batch that cannot be unpacked is left out whole, with
an error line, and a gap in a node's batch sequence is reported as lost.

Prints ``recorder ready`` on stdout once every subscription exists. SIGINT or SIGTERM
stops it: pending messages are drained (until nothing arrives for ``--drain-idle``
seconds, at most ``--drain-timeout`` seconds) and the bag is closed cleanly.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import struct
import sys
import time
from collections import deque
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import FrameType
from typing import Any, Literal

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from rcl_interfaces.msg import ParameterEvent
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rclpy.utilities import remove_ros_args
from rosbags.interfaces import Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.serde import SerdeError
from rosbags.typesys.store import Typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from bracing_analysis import surfaces, truth
from bracing_bringup.scene import Derived, SceneBuilder
from bracing_bringup.topics import (
    COMMAND_TOPICS,
    CONTROLLER_NODE,
    DESCRIPTION_TOPIC,
    OPTIONAL_STATE_TOPICS,
    PARAMETER_EVENTS_TOPIC,
    RECORDER_NODE,
    SCENE_TOPICS,
    missing_from_counts,
    recorded_topics,
    target_topics,
    target_verdict_topics,
)
from bracing_bringup.topics import expected_counts as expected_counts  # re-exported: the check lives in topics
from bracing_core.kinematics import DescriptionError
from bracing_core.overrides import SIMULATOR
from bracing_core.record_batch import BatchError, unpack
from bracing_core.typestore import BRACING_MSGS as BRACING_MSGS  # re-exported: the typestore lives in bracing_core
from bracing_core.typestore import (
    CLOCK,
    CONTACTS,
    CONTROLLER_STATE,
    DIAGNOSTIC_STATUS,
    JOINT_STATE,
    MOTOR_COMMAND,
    MOTOR_STATE,
    ODOMETRY,
    PARAMETER_EVENT,
    PATH,
    POINT_STAMPED,
    POSE_STAMPED,
    RUN_STATUS,
    STRING,
    TWIST_STAMPED,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
    bracing_typestore,
)
from bracing_core.typestore import bracing_msgs_dir as bracing_msgs_dir
from bracing_msgs.msg import Contacts, ControllerState, MotorCommand, MotorState, RecordBatch, RunStatus
from bracing_ros.fastdds import use_fastdds_profile
from bracing_ros.lifetime import report_faults, stop_with_parent
from bracing_ros.record_batch import RECORD_BATCH_TOPIC
from bracing_ros.status import STATUS_QOS, STATUS_TOPIC, StatusPublisher
from bracing_ros.waiter import SubscriptionWaiter

BAG_VERSION: Literal[8] = 8
"""rosbag2 metadata version written (8 is read by every Jazzy rosbag2)."""

MAX_SCENE_BACKLOG = 100_000
"""Recorded messages (3 per state, braced) kept for deriving /tf and markers later: ~30 MB, 30 s of a
lockstep run. Deriving cost ~150 us of CPU per state and, done beside the lockstep loop, slowed it
by 20-30 %, so it waits for an idle moment or the end of the run unless the queue grows past this.
(It now costs ~28 us, ~60 us with the writes, measured at the end of a run.) Derived as the batches come
instead (8 s paper runs, four of each alternately) the loop ran 5 % slower (2.39 -> 2.27x real
time; the two nodes alone 2.61x) for a bag closed ~0.4 s sooner after a 10 s run: the recorder's share of a
step stays under 10 % this way."""

LATCHED = Qos(
    history=QosHistory.KEEP_LAST,
    depth=1,
    reliability=QosReliability.RELIABLE,
    durability=QosDurability.TRANSIENT_LOCAL,
    deadline=QosTime(sec=0, nsec=0),
    lifespan=QosTime(sec=0, nsec=0),
    liveliness=QosLiveliness.AUTOMATIC,
    liveliness_lease_duration=QosTime(sec=0, nsec=0),
    avoid_ros_namespace_conventions=False,
)
"""Offered QoS stored for /tf_static and robot_description: ``ros2 bag play`` replays them latched."""

RECORD_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Reliable, deep and transient-local, so that nothing is lost in lockstep runs: a publisher
that starts before the recorder has discovered it still delivers its first messages.
(It matches the nodes' transient-local publishers; a volatile publisher is not recorded.)"""

PARAMETER_EVENTS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""rclpy's own for /parameter_events: its publishers are volatile, which a transient-local
subscription would not match. The targets' too (a script's, RViz's, MoveIt's publishers are volatile)."""

_TARGET_TYPES: dict[str, type] = {
    POINT_STAMPED: PointStamped,
    PATH: PathMsg,
    POSE_STAMPED: PoseStamped,
    DIAGNOSTIC_STATUS: DiagnosticStatus,
    TWIST_STAMPED: TwistStamped,
}


_RCLPY_TYPES: dict[str, type] = {
    JOINT_STATE: JointState,
    WRENCH_STAMPED: WrenchStamped,
    CONTACTS: Contacts,
    MOTOR_STATE: MotorState,
    CLOCK: Clock,
    MOTOR_COMMAND: MotorCommand,
    CONTROLLER_STATE: ControllerState,
    VECTOR3_STAMPED: Vector3Stamped,  # an optional per-state topic (hand_orientation_error)
    ODOMETRY: Odometry,  # an optional per-state topic (odom: a mobile base)
}


def topic_table(contacts: Sequence[str], ground_truth: bool = False) -> list[tuple[str, type, str]]:
    """(relative topic, rclpy type, ROS 2 type name) for every topic recorded once per state."""
    return [(topic, _RCLPY_TYPES[type_name], type_name) for topic, type_name in recorded_topics(contacts, ground_truth)]


def missing_messages(bag: Path, contacts: Sequence[str], expected: int, namespace: str = "") -> list[str]:
    """What a lockstep bag lacks: one line per topic recorded fewer times than it should be
    (see ``topics.expected_counts``)."""
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        counts: dict[str, int] = {}
        for connection in reader.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
    return missing_from_counts(counts, contacts, expected, namespace)


def cdr_stamp_ns(data: bytes) -> int:
    """Stamp [ns] of a CDR message whose first field is a builtin_interfaces/Time.

    True for every recorded type: the std_msgs/Header ones and rosgraph_msgs/Clock.
    """
    endian = "<" if data[1] & 1 else ">"
    sec, nanosec = struct.unpack_from(endian + "iI", data, 4)
    return int(sec) * 1_000_000_000 + int(nanosec)


class Recorder(Node):
    """Subscribes to the bracing topics and writes them to an open rosbag2 writer."""

    def __init__(
        self,
        writer: Writer,
        typestore: Typestore,
        *,
        namespace: str = "",
        contacts: Sequence[str] = (),
        scene: bool = True,
        shapes: Mapping[str, surfaces.Shape] | None = None,
        ground_truth: bool = False,
        from_batches: bool = False,
    ) -> None:
        super().__init__(RECORDER_NODE, namespace=namespace)
        self.writer = writer
        self.typestore = typestore
        self._contacts = list(contacts)
        self.counts: dict[str, int] = {}
        self.received = 0
        self.derived = 0
        self.scene_time = 0.0  # [s] of CPU spent deriving /tf and markers (what the lockstep loop shares)
        self.last_receive = time.monotonic()
        self._recorded: dict[str, tuple[Connection, str]] = {}  # resolved topic: its connection, its role
        self._topic_of: dict[Subscription, str] = {}  # the recorded topics subscribed to one by one
        self._roles: dict[Subscription, str] = {}  # what the scene makes of a subscription's messages
        self._subscribe_recorded(contacts, ground_truth, from_batches)
        self._subscribe_optional(from_batches)
        self._subscribe_events()
        self._batches: Subscription | None = None
        self._next_batch: dict[str, int] = {}  # per node: the sequence number its next batch should have
        subscriptions = [*self._topic_of, *self._optional_of, self._events, self._status, *self._targets]
        if from_batches:
            self._batches = self.create_subscription(RecordBatch, RECORD_BATCH_TOPIC, _never_called, RECORD_QOS)
            subscriptions.append(self._batches)
        self._sim_time_ns = 0  # the last /clock recorded: when a target arrived, on the bag's time axis
        self._waiter = SubscriptionWaiter(self, subscriptions)
        self.scene = SceneBuilder(typestore, contacts, shapes) if scene else None
        self._scene_inputs: deque[tuple[str, bytes]] = deque()
        self._scene_roles = {"joint_states", "contacts", "description", *(f"contact_wrench/{c}" for c in contacts)}
        self._scene_connections: dict[str, Connection] = {}
        if scene:
            self._add_scene_connections(contacts)

    def _subscribe_recorded(self, contacts: Sequence[str], ground_truth: bool, from_batches: bool) -> None:
        """The recorded topics, each with its bag connection from the start; subscribed to one by one
        unless they come in batches (robot_description always is: once, latched)."""
        table = [
            (topic, msg_type, type_name, topic) for topic, msg_type, type_name in topic_table(contacts, ground_truth)
        ]
        table.append((DESCRIPTION_TOPIC, String, STRING, "description"))
        for topic, msg_type, type_name, role in table:
            resolved = self.resolve_topic_name(topic)
            if role == "description" or not from_batches:
                # Messages are taken directly in ``record`` (no executor: per message it costs more
                # than the write), so the callback is never called.
                sub = self.create_subscription(msg_type, topic, _never_called, RECORD_QOS, raw=True)
                self._topic_of[sub] = resolved
                self._roles[sub] = role
            qos = [LATCHED] if role == "description" else []
            connection = self.writer.add_connection(
                resolved, type_name, typestore=self.typestore, offered_qos_profiles=qos
            )
            self._recorded[resolved] = (connection, role)
            self.counts[resolved] = 0

    def _subscribe_optional(self, from_batches: bool) -> None:
        """The per-state topics only some configurations publish (``topics.OPTIONAL_STATE_TOPICS``): each
        enters the bag with its first message (subscribed to one by one unless they come in batches)."""
        self._optional: dict[str, str] = {}  # resolved topic: its type name
        self._optional_of: dict[Subscription, str] = {}
        self._optional_connections: dict[str, Connection] = {}
        for topic, type_name in OPTIONAL_STATE_TOPICS:
            resolved = self.resolve_topic_name(topic)
            self._optional[resolved] = type_name
            if not from_batches:
                sub = self.create_subscription(_RCLPY_TYPES[type_name], topic, _never_called, RECORD_QOS, raw=True)
                self._optional_of[sub] = resolved

    def _write_optional(self, topic: str, data: bytes) -> None:
        """One message of an optional per-state topic (resolved name), at its header stamp."""
        connection = self._optional_connections.get(topic)
        if connection is None:
            connection = self.writer.add_connection(topic, self._optional[topic], typestore=self.typestore)
            self._optional_connections[topic] = connection
            self.counts[topic] = 0
        self.writer.write(connection, max(cdr_stamp_ns(data), 0), data)
        self.counts[topic] += 1

    def _subscribe_events(self) -> None:
        """Parameter changes, run_status and the targets: each topic enters the bag with its first message."""
        # The controller's parameter changes, on rclpy's volatile topic (see ``_record_event``); a run
        # without any has no such topic.
        self._events = self.create_subscription(
            ParameterEvent, PARAMETER_EVENTS_TOPIC, _never_called, PARAMETER_EVENTS_QOS, raw=True
        )
        self._events_connection: Connection | None = None
        self._roles[self._events] = "parameter_events"
        self._controller = self.resolve_topic_name(CONTROLLER_NODE)  # its fully qualified name
        # The run's warnings, from run_status (see ``_record_status``).
        self._status = self.create_subscription(RunStatus, STATUS_TOPIC, _never_called, STATUS_QOS, raw=True)
        self._status_connection: Connection | None = None
        self._roles[self._status] = "run_status"
        self.simulator_heard = False  # a simulator speaks on run_status (its CONFIGURED is kept for late subscribers)
        self.simulator_finished = False  # its FINISHED status came: nothing more from it
        self._targets: dict[Subscription, str] = {}
        self._target_connections: dict[Subscription, Connection] = {}
        commands = [*target_topics(self._contacts), *target_verdict_topics(self._contacts), *COMMAND_TOPICS]
        for topic, type_name in commands:
            sub = self.create_subscription(
                _TARGET_TYPES[type_name], topic, _never_called, PARAMETER_EVENTS_QOS, raw=True
            )
            self._targets[sub] = type_name
            self._roles[sub] = "target"

    def _add_scene_connections(self, contacts: Sequence[str]) -> None:
        """/tf, /tf_static and the contact markers the recorder derives."""
        for key, (topic, type_name) in SCENE_TOPICS.items():
            if key == "contact_markers" and not contacts:
                continue  # nothing to mark
            resolved = self.resolve_topic_name(topic)
            qos = [LATCHED] if key == "tf_static" else []
            self._scene_connections[key] = self.writer.add_connection(
                resolved, type_name, typestore=self.typestore, offered_qos_profiles=qos
            )
            self.counts[resolved] = 0

    def record(self, timeout_sec: float) -> int:
        """Write every message available now, waiting up to ``timeout_sec``; the count of samples taken."""
        taken = self._waiter.take_all(timeout_sec)
        written = 0
        for sub, data in taken:
            if sub is self._batches:
                written += self._record_batch(data)
            elif sub is self._events:
                written += self._record_event(data)
            elif sub is self._status:
                written += self._record_status(data)
            elif sub in self._targets:
                self._record_target(sub, data)
                written += 1
            elif sub in self._optional_of:
                self._write_optional(self._optional_of[sub], data)
                written += 1
            else:
                self._write(self._topic_of[sub], data)
                written += 1
        if taken:
            self.received += written
            self.last_receive = time.monotonic()
        return len(taken)

    def _write(self, topic: str, data: bytes) -> None:
        """One message of a recorded topic (resolved name) into the bag, at its header stamp (at 0 if that
        is negative: mcap's log time is unsigned; a negative /clock ended the recorder with OverflowError)."""
        connection, role = self._recorded[topic]
        stamp = 0 if role == "description" else max(cdr_stamp_ns(data), 0)
        if role == "/clock":
            self._sim_time_ns = stamp
        self.writer.write(connection, stamp, data)
        self.counts[topic] += 1
        if self.scene is not None and role in self._scene_roles:
            self._scene_inputs.append((role, data))

    def _record_batch(self, batch: RecordBatch) -> int:
        """Write a RecordBatch's messages, each under its own topic; the count written (0 for a batch
        that cannot be unpacked, or that names a topic this recorder does not record)."""
        expected = self._next_batch.get(batch.node, 0)
        if batch.sequence != expected:
            lost = f"{batch.sequence - expected} batch(es)" if batch.sequence > expected else "a batch out of order"
            print(f"recorder: error: {lost} from {batch.node} lost (sequence {batch.sequence})", file=sys.stderr)
        self._next_batch[batch.node] = batch.sequence + 1
        try:
            messages = unpack(batch.topics, batch.topic_of, batch.end, batch.data)
            unknown = sorted({t for t in batch.topics if t not in self._recorded and t not in self._optional})
            if unknown:
                raise BatchError(f"it names topics this recorder does not record: {', '.join(unknown)}")
        except BatchError as exc:
            print(f"recorder: error: a record_batch from {batch.node} left out: {exc}", file=sys.stderr, flush=True)
            return 0
        for topic, data in messages:
            if topic in self._optional:
                self._write_optional(topic, data)
            else:
                self._write(topic, data)
        return len(messages)

    def _record_event(self, data: bytes) -> bool:
        """Write a /parameter_events message if it is worth the bag: the run's controller changing a value.
        (Every node announces its parameters there when it starts, stamped with the wall clock; the
        controller stamps its changes with the sim time, the bag's time axis.) Whether it was written."""
        try:
            event: Any = self.typestore.deserialize_cdr(data, PARAMETER_EVENT)
        except (SerdeError, ValueError, IndexError, KeyError):
            return False
        if event.node != self._controller or not (len(event.changed_parameters) or len(event.deleted_parameters)):
            return False
        if self._events_connection is None:
            topic = self._events.topic_name
            self._events_connection = self.writer.add_connection(topic, PARAMETER_EVENT, typestore=self.typestore)
            self.counts[topic] = 0
        self.writer.write(self._events_connection, cdr_stamp_ns(data), data)
        self.counts[self._events_connection.topic] += 1
        return True

    def _record_status(self, data: bytes) -> bool:
        """Write a run_status message if it is a warning (stamped with its sim time, 0 if it has none);
        note the simulator's FINISHED. Whether it was written."""
        try:
            status: Any = self.typestore.deserialize_cdr(data, RUN_STATUS)
        except (SerdeError, ValueError, IndexError, KeyError):
            return False
        if status.node == SIMULATOR:
            self.simulator_heard = True
            self.simulator_finished |= status.event == status.FINISHED
        if status.event != status.WARNING:
            return False
        if self._status_connection is None:
            topic = self._status.topic_name
            self._status_connection = self.writer.add_connection(topic, RUN_STATUS, typestore=self.typestore)
            self.counts[topic] = 0
        stamp = round(status.sim_time * 1e9) if math.isfinite(status.sim_time) else 0
        self.writer.write(self._status_connection, max(stamp, 0), data)
        self.counts[self._status_connection.topic] += 1
        return True

    @property
    def simulator_done(self) -> bool:
        """Nothing more to come from the simulator on run_status: it said FINISHED, or none speaks there."""
        return self.simulator_finished or not self.simulator_heard

    def _record_target(self, sub: Subscription, data: bytes) -> None:
        """Write a target as it came, at the sim time of the last /clock recorded (the bag's time axis);
        its topic enters the bag with its first message."""
        connection = self._target_connections.get(sub)
        if connection is None:
            connection = self.writer.add_connection(sub.topic_name, self._targets[sub], typestore=self.typestore)
            self._target_connections[sub] = connection
            self.counts[connection.topic] = 0
        self.writer.write(connection, self._sim_time_ns, data)
        self.counts[connection.topic] += 1

    def has_every_message(self, wanted: Mapping[str, int]) -> bool:
        """Whether every subscribed topic has ``wanted[topic]`` messages (``topics.expected_counts``)."""
        return all(self.counts[topic] >= wanted[topic] for topic in self._recorded)

    @property
    def scene_backlog(self) -> int:
        """Recorded messages the scene has yet to derive from."""
        return len(self._scene_inputs) if self.scene is not None else 0

    def derive(self, budget_sec: float | None) -> int:
        """Derive /tf, /tf_static and contact_markers from the queued messages for about ``budget_sec``
        (None: all of them); the backlog left.

        Deriving comes second to recording (see ``MAX_SCENE_BACKLOG``): messages are written as
        they come and queued for the scene, which takes its slices when the recorder is idle."""
        deadline = math.inf if budget_sec is None else time.monotonic() + budget_sec
        while self.scene_backlog and time.monotonic() < deadline:
            slice_ = [self._scene_inputs.popleft() for _ in range(min(32, len(self._scene_inputs)))]
            self._write_scene(slice_)
        return self.scene_backlog

    def _write_scene(self, inputs: list[tuple[str, bytes]]) -> None:
        """/tf, /tf_static and contact_markers of recorded messages (role, CDR bytes)."""
        scene = self.scene
        assert scene is not None
        start = time.thread_time()
        derived: list[Derived] = []
        try:
            for role, data in inputs:
                if role == "joint_states":
                    derived += scene.joint_state(cdr_stamp_ns(data), data)
                elif role == "contacts":
                    derived += scene.contacts(cdr_stamp_ns(data), data)
                elif role.startswith("contact_wrench/"):
                    derived += scene.wrench(role.removeprefix("contact_wrench/"), cdr_stamp_ns(data), data)
                elif role == "description":
                    derived += scene.description(data)
        except (DescriptionError, SerdeError, ValueError, IndexError, KeyError) as exc:  # bytes it cannot read
            print(f"recorder: error: no /tf or contact_markers from here on: {exc}", file=sys.stderr, flush=True)
            self.scene = None
            self._scene_inputs.clear()
        write, connections, counts = self.writer.write, self._scene_connections, self.counts
        for item in derived:
            connection = connections.get(item.key)
            if connection is not None:
                write(connection, item.stamp_ns, item.data)
                counts[connection.topic] += 1
        self.derived += len(derived)
        self.scene_time += time.thread_time() - start


def _never_called(_: object) -> None:
    raise AssertionError("the recorder takes its messages itself")


def _scenario_surfaces(files: Sequence[str]) -> dict[str, surfaces.Shape]:
    """The contact surfaces of the scenario files (none given or unreadable: none, said so; the
    markers then draw each surface as its tangent plane)."""
    if not files:
        return {}
    try:
        return surfaces.read_scenario(files)
    except ValueError as exc:  # ConfigError: the nodes will say the same, more loudly
        print(f"recorder: warning: no contact surfaces from {', '.join(files)}: {exc}", file=sys.stderr, flush=True)
        return {}


def _task_notes(files: Sequence[str], ground_truth: bool) -> dict[str, str]:
    """The controller's task frames (the report judges the truth at them: truth.py), task axes (the report
    draws each) and input mode, as the bag's custom_data; none if unreadable."""
    if not files:
        return {}
    try:
        return truth.read_task_notes(files, ground_truth)
    except ValueError as exc:  # ConfigError: the nodes will say the same, more loudly
        print(f"recorder: warning: no task frames or axes from {', '.join(files)}: {exc}", file=sys.stderr, flush=True)
        return {}


def _scene_notes(scenario: str | None, shapes: Mapping[str, surfaces.Shape]) -> dict[str, str]:
    """The scenario's name and contact surfaces, as the bag's custom_data."""
    notes = {surfaces.SCENARIO_KEY: scenario} if scenario else {}
    if shapes:
        notes[surfaces.SURFACES_KEY] = surfaces.to_json(shapes)
    return notes


def bag_notes(params_files: Sequence[str], scenario: str | None, ground_truth: bool) -> dict[str, str]:
    """The custom_data the recorder writes into the bag's metadata when it closes the bag (run with these
    ``--params-file``, ``--scenario`` and ``--ground-truth``): what a bag recovered after its recorder died
    is given again (``bracing_analysis.bag_recovery``)."""
    scenario = scenario or (Path(params_files[0]).stem if params_files else None)
    notes = {**_scene_notes(scenario, _scenario_surfaces(params_files)), **_task_notes(params_files, ground_truth)}
    return {**notes, **_command_limit_notes(params_files)}


def _parse(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="bracing-recorder",
        description="Record the bracing topics to a rosbag2 bag (mcap storage).",
    )
    parser.add_argument("--output", required=True, help="bag directory to create (must not exist)")
    parser.add_argument("--namespace", default="", help="namespace of the recorded nodes")
    parser.add_argument("--contacts", default="", help="comma-separated contact names (contact_wrench/<name>)")
    parser.add_argument(
        "--ground-truth",
        action="store_true",
        help="also record ground_truth/joint_states and ground_truth/motor_state (a simulator with sensors.*)",
    )
    parser.add_argument(
        "--params-file",
        dest="params_files",
        action="append",
        default=[],
        metavar="FILE",
        help="a params file the nodes run with (repeat for each, in order): its contact surfaces go into the bag's "
        "metadata, and the markers draw spheres and cylinders as such",
    )
    parser.add_argument(
        "--scenario",
        default=None,
        metavar="NAME",
        help="the scenario's name, kept in the bag's metadata for the report (default: the first params file's name)",
    )
    parser.add_argument(
        "--batch",
        type=float,
        default=0.005,
        help="after writing, let messages gather for this long before waiting again [s] (default 0.005): "
        "one wake-up per batch instead of one per message leaves the CPU to the nodes",
    )
    parser.add_argument(
        "--niceness", type=int, default=0, help="add this to the process's nice value (bracing-pair uses 10)"
    )
    parser.add_argument(
        "--no-scene",
        action="store_true",
        help="record only what arrives: no /tf, /tf_static or contact_markers (they cost CPU per state)",
    )
    parser.add_argument(
        "--from-batches",
        action="store_true",
        help="take the per-state topics from the nodes' record_batch (their record_batch parameter > 0; "
        "bracing-pair sets both) instead of subscribing to each: one DDS delivery per batch, not per message",
    )
    parser.add_argument(
        "--expect-states",
        type=int,
        default=0,
        help="the states of a lockstep run: close the bag as soon as every topic has its messages "
        "(default 0: only when stopped)",
    )
    parser.add_argument(
        "--drain-idle", type=float, default=0.2, help="on stop, keep receiving until idle this long [s] (default 0.2)"
    )
    parser.add_argument(
        "--drain-timeout",
        type=float,
        default=60.0,
        help="on stop, drain for at most this long [s] (default 60: a recorder that fell behind on a busy "
        "machine may hold many messages in its queues, all acknowledged to their publishers)",
    )
    return parser.parse_args(list(argv))


class StopRequest:
    """SIGINT/SIGTERM: the first asks the recorder to drain and close the bag, a second to close it
    at once (still a readable bag)."""

    def __init__(self) -> None:
        self.requested = False
        self.urgent = False

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        del signum, frame
        if self.requested:
            self.urgent = True  # second signal: skip the drain, still close the bag
        self.requested = True


def _open_writer(output: Path, scenario: str | None, shapes: Mapping[str, surfaces.Shape]) -> Writer:
    writer = Writer(output, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
    for key, value in _scene_notes(scenario, shapes).items():
        writer.set_custom_data(key, value)
    writer.open()
    return writer


def _write_task_metadata(writer: Writer, params_files: list[str], ground_truth: bool) -> None:
    """Read while the nodes start (custom_data is written when the bag closes): off the start's path."""
    for key, value in {**_task_notes(params_files, ground_truth), **_command_limit_notes(params_files)}.items():
        writer.set_custom_data(key, value)


def _command_limit_notes(files: Sequence[str]) -> dict[str, str]:
    """The motors' |command| saturation by joint (truth.read_command_limits), where a joint has one, as the
    bag's custom_data (summary.json's saturation_fraction); none if unreadable."""
    if not files:
        return {}
    try:
        limits = truth.read_command_limits(files)
    except (ValueError, OSError) as exc:  # ConfigError, an unreadable URDF: the nodes will say so too
        print(f"recorder: warning: no command limits from {', '.join(files)}: {exc}", file=sys.stderr, flush=True)
        return {}
    if not any(limit > 0.0 for limit in limits.values()):
        return {}
    return {truth.COMMAND_LIMIT_KEY: json.dumps(limits, sort_keys=True)}


def _record_until_stopped(node: Recorder, args: argparse.Namespace, stop: StopRequest, contacts: list[str]) -> bool:
    """Record until a stop signal, or until every expected message is in; True in the latter case."""
    idle = False
    wanted = (
        expected_counts(contacts, args.expect_states, node.get_namespace(), args.ground_truth)
        if args.expect_states
        else None
    )
    while not stop.requested:
        got = node.record(0.0 if idle and node.scene_backlog else 0.1)
        idle = not got
        if got and wanted is not None and node.simulator_done and node.has_every_message(wanted):
            return True  # nothing more will come (the simulator's last warning came before FINISHED): no drain
        if node.scene_backlog and (idle or node.scene_backlog > MAX_SCENE_BACKLOG):
            node.derive(0.05)  # idle (nothing came for 0.1 s), or the queue would grow too large
        elif got and args.batch > 0.0:
            time.sleep(args.batch)  # messages wait in the subscriptions' queues (deep, reliable)
    return False


def _drain(node: Recorder, args: argparse.Namespace, stop: StopRequest, complete: bool) -> None:
    """Receive what is still in flight until idle for drain_idle (bounded), then derive the rest of
    the scene: the bag has /tf and markers for every state it holds."""
    start = time.monotonic()
    node.last_receive = start
    while not stop.urgent and not complete:
        now = time.monotonic()
        if now - node.last_receive >= args.drain_idle or now - start >= args.drain_timeout:
            break
        node.record(0.05)
        node.derive(0.01)
    while not stop.urgent and node.derive(0.1):
        pass


def _close(writer: Writer, node: Recorder | None, status: StatusPublisher | None, output: Path) -> None:
    writer.close()
    print(f"recorder closed the bag at {time.time():.6f}", flush=True)
    if status is not None:
        status.say(RunStatus.BAG_CLOSED)
        status.flush()  # bracing-pair has it before this process ends
    total = node.received if node is not None else 0
    print(f"recorder wrote {total} messages to {output}", flush=True)
    if node is not None and node.derived:
        states = node.counts.get("/tf", 0)
        cost = f", {node.scene_time / states * 1e6:.0f} us of CPU per state" if states else ""
        print(f"recorder derived {node.derived} messages (/tf, /tf_static, contact_markers){cost}", flush=True)
    if node is not None:
        node.destroy_node()
    if rclpy.ok():
        rclpy.shutdown()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the recorder until SIGINT/SIGTERM; returns the exit code."""
    report_faults()  # its stack on a crash, and every thread's on SIGUSR1 (a hang)
    full = list(sys.argv[1:] if argv is None else argv)
    args = _parse(remove_ros_args(["recorder", *full])[1:])
    contacts = [c.strip() for c in args.contacts.split(",") if c.strip()]
    output = Path(args.output)
    if output.exists():
        print(f"recorder: error: {output} exists already, not overwriting", file=sys.stderr)
        return 2
    stop = StopRequest()
    signal.signal(signal.SIGINT, stop.on_signal)
    signal.signal(signal.SIGTERM, stop.on_signal)
    stop_with_parent()  # a SIGKILLed bracing-pair still gets its bag closed
    try:
        typestore = bracing_typestore()
    except (FileNotFoundError, OSError) as exc:
        print(f"recorder: error: {exc}", file=sys.stderr)
        return 2
    shapes = _scenario_surfaces(args.params_files)
    scenario = args.scenario or (Path(args.params_files[0]).stem if args.params_files else None)
    if args.niceness:
        os.nice(args.niceness)
    use_fastdds_profile()  # the nodes' discovery settings: matched at once when started together
    rclpy.init(args=["recorder", *full], signal_handler_options=SignalHandlerOptions.NO)
    writer = _open_writer(output, scenario, shapes)
    node: Recorder | None = None
    status: StatusPublisher | None = None
    try:
        node = Recorder(
            writer,
            typestore,
            namespace=args.namespace,
            contacts=contacts,
            scene=not args.no_scene,
            shapes=shapes,
            ground_truth=args.ground_truth,
            from_batches=args.from_batches,
        )
        status = StatusPublisher(node)  # what bracing-pair follows
        status.say(RunStatus.READY)
        print(f"recorder subscribed at {time.time():.6f}", flush=True)
        print("recorder ready", flush=True)
        _write_task_metadata(writer, args.params_files, args.ground_truth)
        complete = _record_until_stopped(node, args, stop, contacts)
        _drain(node, args, stop, complete)
    finally:
        _close(writer, node, status, output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
