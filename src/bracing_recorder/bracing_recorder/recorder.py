"""Record every topic of the bracing interface to a rosbag2 bag (mcap storage).

Usage (``command.py``; ``python -m bracing_recorder.command`` is the same)::

    bracing-recorder --output DIR/bag [--namespace NS] \
        [--contacts elbow,...] [--params-file FILE ...] [--scenario NAME] [--ros-args ...]

The bag embeds the message definitions (bracing_msgs included), so any rosbag2 reader
decodes it. Messages are received already serialised (CDR, ``raw=True``) and written as
they are; the bag timestamp of a message is its header stamp (``clock`` for ``/clock``,
0 for ``robot_description``).

So that a viewer can draw the run, the recorder also writes what it derives from the
recorded messages (``bracing_recorder.scene``): ``/tf_static`` once and ``/tf`` per
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
``bracing_analysis.bag_recovery`` rewrites whole (``bag_notes.bag_notes`` gives its metadata again).

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
closed once every topic has its messages and the simulator has said FINISHED on run_status (after its last
warning: one writer, in order). Only FINISHED says nothing more will come: a reader of run_status that
matches the simulator's writer late hears nothing of it until then, and a 0.3 s run can end before that.
Such a lockstep bag is written after the last step: the messages are taken as they come (the nodes' flow
control sees them acknowledged) and kept, then written at FINISHED in the order they came, the same bag
byte for byte (``Recorder.record``'s ``defer``; at once past ``MAX_RECORD_BACKLOG``, or when nothing came for
0.1 s). The loop's CPU is not shared with the bag's writing; the recorder logs the share of a core it took
while the run stepped (``command.STEPPING_CPU_LINE``, make bench's ``recorder_cpu_share_of_step``).

With ``--from-batches`` the per-state topics come in ``bracing_msgs/RecordBatch`` samples on
``record_batch`` (the nodes' ``record_batch`` parameter; bracing-pair sets both): each message is
written under its own topic, exactly as if it had come on it, without one DDS delivery per message
(``bracing_core.record_batch`` says why); a batch's messages go into the bag in one piece, the bag byte for
byte the one written message by message (``bag_batch``: rosbags' per-message Python was most of the
recorder's CPU per state). A batch that cannot be unpacked is left out whole, with
an error line, and a gap in a node's batch sequence is reported as lost.

With ``--stay`` (and ``--expect-states``) a closed bag is followed by the next one asked for, in the same
process (``bag_switch``): runs that reuse their nodes reuse their recorder too.

Prints ``recorder ready`` on stdout once every subscription exists (and again as each next bag opens). SIGINT or SIGTERM
stops it: pending messages are drained (until nothing arrives for ``--drain-idle``
seconds, at most ``--drain-timeout`` seconds) and the bag is closed cleanly.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from rcl_interfaces.msg import ParameterEvent
from rclpy.node import Node
from rclpy.subscription import Subscription
from rosbags.interfaces import Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.serde import SerdeError
from rosbags.typesys.store import Typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from bracing_analysis import surfaces
from bracing_core.kinematics import DescriptionError
from bracing_core.overrides import SIMULATOR
from bracing_core.stamps import cdr_stamp_ns
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
)
from bracing_core.typestore import bracing_msgs_dir as bracing_msgs_dir
from bracing_msgs.msg import Contacts, ControllerState, MotorCommand, MotorState, RecordBatch, RunStatus
from bracing_recorder.bag_batch import BagWriter
from bracing_recorder.batch_writing import BatchWriting
from bracing_recorder.scene import Derived, SceneBuilder
from bracing_recorder.topics import (
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
from bracing_recorder.topics import expected_counts as expected_counts  # re-exported: the check lives in topics
from bracing_ros.qos import PARAMETER_EVENTS_QOS, RECORD_QOS, STATUS_QOS
from bracing_ros.record_batch import RECORD_BATCH_TOPIC
from bracing_ros.status import STATUS_TOPIC
from bracing_ros.waiter import SubscriptionWaiter

BAG_VERSION: Literal[8] = 8
"""rosbag2 metadata version written (8 is read by every Jazzy rosbag2)."""

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


MAX_RECORD_BACKLOG = 32 * 2**20
"""[bytes] of batches ``Recorder.record(defer=True)`` keeps unwritten while a lockstep run steps (a 10 s paper
run brings ~10 MB): past it, they are written then, beside the loop. Written as they came, the bag's writing
took about half of the recorder's process CPU while the pair stepped (23 -> 11 us per state kept, paper arm,
on the two cores the nodes share); kept, it is written after the simulator's FINISHED, the same bytes in the
same order, while the nodes stop."""


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
    (see ``topics.expected_counts``; the counts from the bag's metadata, ``bracing_analysis.bag``)."""
    from bracing_analysis.bag import topic_counts  # rosbags' reader: only where a bag is read

    return missing_from_counts(topic_counts(bag), contacts, expected, namespace)


class Recorder(BatchWriting, Node):
    """Subscribes to the bracing topics and writes them to an open rosbag2 writer."""

    def __init__(
        self,
        writer: BagWriter,
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
        self.typestore = typestore
        self._contacts = list(contacts)
        self._scene_wanted = scene
        self._recorded_table: list[tuple[str, str, str]] = []  # resolved topic, type name, role: in connection order
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
        self._waiter = SubscriptionWaiter(self, subscriptions)
        per_state = [sub for sub, role in self._roles.items() if sub in self._topic_of and role != "description"]
        self._per_state = {*per_state, *self._optional_of, *([self._batches] if self._batches else [])}
        self._scene_roles = {"joint_states", "contacts", "description", *(f"contact_wrench/{c}" for c in contacts)}
        self.description: bytes | None = None  # the robot_description received (latched: delivered once)
        self._open_bag(writer, shapes)

    def _open_bag(self, writer: BagWriter, shapes: Mapping[str, surfaces.Shape] | None) -> None:
        """Record into ``writer`` from now on, its connections added in the order a new recorder adds them
        (the recorded topics, then the scene's); every count and the scene from the start."""
        self.writer = writer
        self.counts: dict[str, int] = {}
        self.received = 0
        self.derived = 0
        self.scene_time = 0.0  # [s] of CPU spent deriving /tf and markers (what the lockstep loop shares)
        self.record_time = 0.0  # [s] of CPU spent taking and writing messages (what the lockstep loop shares)
        self.stepping_cpu: tuple[float, float, float, float] | None = None  # see ``_note_stepping_cpu``
        self._pending: deque[tuple[Subscription, Any]] = deque()  # taken, not yet written (``record(defer=True)``)
        self._pending_bytes = 0
        self._finish_taken = False  # the simulator's FINISHED is among the samples taken: the run stepped its last
        self.last_receive = time.monotonic()
        self._recorded: dict[str, tuple[Connection, str]] = {}  # resolved topic: its connection, its role
        for resolved, type_name, role in self._recorded_table:
            qos = [LATCHED] if role == "description" else []
            connection = writer.add_connection(resolved, type_name, typestore=self.typestore, offered_qos_profiles=qos)
            self._recorded[resolved] = (connection, role)
            self.counts[resolved] = 0
        self._optional_connections: dict[str, Connection] = {}
        self._events_connection: Connection | None = None
        self._status_connection: Connection | None = None
        self._target_connections: dict[Subscription, Connection] = {}
        self.simulator_finished = False  # its FINISHED status came: nothing more from it
        self._sim_time_ns = 0  # the last /clock recorded: when a target arrived, on the bag's time axis
        self.scene = SceneBuilder(self.typestore, self._contacts, shapes) if self._scene_wanted else None
        self._scene_inputs: deque[tuple[str, bytes]] = deque()
        self._scene_connections: dict[str, Connection] = {}
        if self.scene is not None:
            self._add_scene_connections(self._contacts)

    def next_bag(self, writer: BagWriter, shapes: Mapping[str, surfaces.Shape] | None = None) -> None:
        """Go on recording into ``writer`` (a new bag; the last one closed, its scene derived) as a recorder
        started now would: the same connections, the counts and the scene from the start, and the robot
        description the simulator latched (delivered once, to the first bag) written first again."""
        self._open_bag(writer, shapes)
        if self.description is not None:
            self._write(self.resolve_topic_name(DESCRIPTION_TOPIC), self.description)
            self.received = 1

    def skip(self, timeout_sec: float) -> int:
        """Between bags: take what comes (waiting up to ``timeout_sec``) without writing it (no bag is open),
        keeping the batches' sequence and the simulator's FINISHED; the count taken."""
        taken = self._waiter.take_all(timeout_sec)
        for sub, data in taken:
            if sub is self._batches:
                self._next_batch[data.node] = data.sequence + 1
            elif sub is self._status:
                self._record_status(data, write=False)
        return len(taken)

    def _subscribe_recorded(self, contacts: Sequence[str], ground_truth: bool, from_batches: bool) -> None:
        """The recorded topics (each with its bag connection from the start: ``_open_bag``); subscribed to one
        by one unless they come in batches (robot_description always is: once, latched)."""
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
            self._recorded_table.append((resolved, type_name, role))

    def _subscribe_optional(self, from_batches: bool) -> None:
        """The per-state topics only some configurations publish (``topics.OPTIONAL_STATE_TOPICS``): each
        enters the bag with its first message (subscribed to one by one unless they come in batches)."""
        self._optional: dict[str, str] = {}  # resolved topic: its type name
        self._optional_of: dict[Subscription, str] = {}
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
        self._roles[self._events] = "parameter_events"
        self._controller = self.resolve_topic_name(CONTROLLER_NODE)  # its fully qualified name
        # The run's warnings, from run_status (see ``_record_status``).
        self._status = self.create_subscription(RunStatus, STATUS_TOPIC, _never_called, STATUS_QOS, raw=True)
        self._roles[self._status] = "run_status"
        self._targets: dict[Subscription, str] = {}
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

    def record(self, timeout_sec: float, defer: bool = False) -> int:
        """Write every message available now, waiting up to ``timeout_sec``; the count of samples taken.

        ``defer``: while the simulator has not said FINISHED, keep what is taken to write it later, in the
        order it came (``write_pending``: at the next call without ``defer``, at FINISHED, or once the taken
        batches pass ``MAX_RECORD_BACKLOG`` bytes), so that a lockstep run's loop does not share the CPU
        with the bag's writing."""
        start = time.thread_time()  # the wait costs no CPU; the take and the writing do
        ready = self._waiter.wait(timeout_sec)
        arrived = (time.process_time(), time.monotonic())
        taken = self._waiter.take_ready(ready)
        self._pending.extend(taken)
        self._pending_bytes += sum(len(data.data) for sub, data in taken if sub is self._batches)
        self._finish_taken |= any(self._says_finished(data) for sub, data in taken if sub is self._status)
        if not defer or self._finish_taken or self._pending_bytes > MAX_RECORD_BACKLOG:
            self.write_pending()
        if taken:
            self.last_receive = arrived[1]
            if not self._finish_taken and not self._per_state.isdisjoint(sub for sub, _ in taken):
                self._note_stepping_cpu(arrived)
        self.record_time += time.thread_time() - start
        return len(taken)

    def write_pending(self) -> None:
        """Write what was taken and not yet written (``record``'s ``defer``), in the order it came."""
        written = 0
        while self._pending:
            written += self._write_taken(*self._pending.popleft())
        self._pending_bytes = 0
        self.received += written

    def _write_taken(self, sub: Subscription, data: Any) -> int:
        """One sample taken from ``sub`` into the bag as its topic is recorded; the count of messages written."""
        if sub is self._batches:
            return self._record_batch(data)
        if sub is self._events:
            return int(self._record_event(data))
        if sub is self._status:
            return int(self._record_status(data))
        if sub in self._targets:
            self._record_target(sub, data)
        elif sub in self._optional_of:
            self._write_optional(self._optional_of[sub], data)
        else:
            self._write(self._topic_of[sub], data)
        return 1

    def _says_finished(self, data: bytes) -> bool:
        """Whether a run_status sample is the simulator's FINISHED (one that cannot be read is not)."""
        try:
            status: Any = self.typestore.deserialize_cdr(data, RUN_STATUS)
        except (SerdeError, ValueError, IndexError, KeyError):
            return False
        return bool(status.node == SIMULATOR and status.event == status.FINISHED)

    def _note_stepping_cpu(self, arrived: tuple[float, float]) -> None:
        """After a take of per-state messages before the simulator's FINISHED whose samples ``arrived`` at
        (``time.process_time``, ``time.monotonic``): ``stepping_cpu``, the process's CPU time (every thread's:
        DDS's receiving too) and the wall time [s] when the first such take's samples arrived and after the
        latest. What the recorder costs the machine while a run steps, without its start-up (imports, the
        robot's model), nor the end's writing and scene (``stepping_cpu_share``)."""
        first = arrived if self.stepping_cpu is None else self.stepping_cpu[:2]
        self.stepping_cpu = (*first, time.process_time(), time.monotonic())

    @property
    def stepping_cpu_share(self) -> float | None:
        """The recorder process's CPU time over the wall time while the run stepped (``_note_stepping_cpu``): the
        share of one core it took, which is its CPU time per state over a step. None before any such take."""
        if self.stepping_cpu is None or self.stepping_cpu[3] <= self.stepping_cpu[1]:
            return None
        cpu_first, wall_first, cpu_last, wall_last = self.stepping_cpu
        return (cpu_last - cpu_first) / (wall_last - wall_first)

    def _write(self, topic: str, data: bytes) -> None:
        """One message of a recorded topic (resolved name) into the bag, at its header stamp (at 0 if that
        is negative: mcap's log time is unsigned; a negative /clock ended the recorder with OverflowError)."""
        connection, role = self._recorded[topic]
        stamp = 0 if role == "description" else max(cdr_stamp_ns(data), 0)
        if role == "description":
            self.description = data  # for the next bag (``next_bag``)
        elif role == "/clock":
            self._sim_time_ns = stamp
        self.writer.write(connection, stamp, data)
        self.counts[topic] += 1
        if self.scene is not None and role in self._scene_roles:
            self._scene_inputs.append((role, data))

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

    def _record_status(self, data: bytes, write: bool = True) -> bool:
        """Write a run_status message if it is a warning (stamped with its sim time, 0 if it has none) and
        ``write``; note the simulator's FINISHED. Whether it was written."""
        try:
            status: Any = self.typestore.deserialize_cdr(data, RUN_STATUS)
        except (SerdeError, ValueError, IndexError, KeyError):
            return False
        if status.node == SIMULATOR:
            self.simulator_finished |= status.event == status.FINISHED
        if status.event != status.WARNING or not write:
            return False
        if self._status_connection is None:
            topic = self._status.topic_name
            self._status_connection = self.writer.add_connection(topic, RUN_STATUS, typestore=self.typestore)
            self.counts[topic] = 0
        stamp = round(status.sim_time * 1e9) if math.isfinite(status.sim_time) else 0
        self.writer.write(self._status_connection, max(stamp, 0), data)
        self.counts[self._status_connection.topic] += 1
        return True

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

        Deriving comes second to recording (see ``command.MAX_SCENE_BACKLOG``): messages are written as
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
        kept = [(self._scene_connections[item.key], item) for item in derived if item.key in self._scene_connections]
        if kept:
            data = b"".join(item.data for _, item in kept)
            self.writer.write_batch(
                np.array([connection.id for connection, _ in kept], np.uint16),
                np.maximum([item.stamp_ns for _, item in kept], 0),  # as the recorded messages' (mcap's is unsigned)
                np.frombuffer(data, np.uint8),
                np.cumsum([len(item.data) for _, item in kept]),
            )
        for connection, _ in kept:
            self.counts[connection.topic] += 1
        self.derived += len(derived)
        self.scene_time += time.thread_time() - start


def _never_called(_: object) -> None:
    raise AssertionError("the recorder takes its messages itself")
