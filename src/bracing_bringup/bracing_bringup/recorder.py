"""Record every topic of the bracing interface to a rosbag2 bag (mcap storage).

Usage::

    python -m bracing_bringup.recorder --output DIR/bag [--namespace NS] \
        [--contacts elbow,...] [--ros-args ...]

The bag embeds the message definitions (bracing_msgs included), so any rosbag2 reader
decodes it. Messages are received already serialised (CDR, ``raw=True``) and written as
they are; the bag timestamp of a message is its header stamp (``clock`` for ``/clock``).

Prints ``recorder ready`` on stdout once every subscription exists. SIGINT or SIGTERM
stops it: pending messages are drained (until nothing arrives for ``--drain-idle``
seconds, at most ``--drain-timeout`` seconds) and the bag is closed cleanly.
"""

from __future__ import annotations

import argparse
import os
import signal
import struct
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import Any, Literal

import rclpy
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rclpy.utilities import remove_ros_args
from rosbags.interfaces import Connection
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from bracing_msgs.msg import Contacts, ControllerState, MotorCommand, MotorState
from bracing_sim.ros_common import SubscriptionWaiter

BAG_VERSION: Literal[8] = 8
"""rosbag2 metadata version written (8 is read by every Jazzy rosbag2)."""

BRACING_MSGS = ("ContactState", "Contacts", "ControllerState", "MotorCommand", "MotorState")

"""Messages taken from one subscription per executor callback."""

RECORD_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Reliable, deep and transient-local, so that nothing is lost in lockstep runs: a publisher
that starts before the recorder has discovered it still delivers its first messages.
(It matches the nodes' transient-local publishers; a volatile publisher is not recorded.)"""


def bracing_msgs_dir() -> Path:
    """Directory of the bracing_msgs ``.msg`` files (installed share dir, else source)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        share = Path(get_package_share_directory("bracing_msgs")) / "msg"
        if all((share / f"{name}.msg").is_file() for name in BRACING_MSGS):
            return share
    except (ImportError, LookupError, ValueError):
        pass
    src = Path(__file__).resolve().parents[2] / "bracing_msgs" / "msg"
    if all((src / f"{name}.msg").is_file() for name in BRACING_MSGS):
        return src
    msg = "cannot find the bracing_msgs .msg files (is the workspace sourced?)"
    raise FileNotFoundError(msg)


def bracing_typestore(msg_dir: Path | None = None) -> Typestore:
    """A Jazzy typestore with the bracing_msgs types registered."""
    store = get_typestore(Stores.ROS2_JAZZY)
    folder = msg_dir if msg_dir is not None else bracing_msgs_dir()
    types: dict[str, Any] = {}
    for name in BRACING_MSGS:
        text = (folder / f"{name}.msg").read_text(encoding="utf-8")
        types.update(get_types_from_msg(text, f"bracing_msgs/msg/{name}"))
    store.register(types)
    return store


def topic_table(contacts: Sequence[str]) -> list[tuple[str, type, str]]:
    """(relative topic, rclpy type, ROS 2 type name) for every recorded topic."""
    table: list[tuple[str, type, str]] = [
        ("joint_states", JointState, "sensor_msgs/msg/JointState"),
    ]
    table += [(f"contact_wrench/{name}", WrenchStamped, "geometry_msgs/msg/WrenchStamped") for name in contacts]
    table += [
        ("contacts", Contacts, "bracing_msgs/msg/Contacts"),
        ("motor_state", MotorState, "bracing_msgs/msg/MotorState"),
        ("/clock", Clock, "rosgraph_msgs/msg/Clock"),
        ("motor_command", MotorCommand, "bracing_msgs/msg/MotorCommand"),
        ("controller_state", ControllerState, "bracing_msgs/msg/ControllerState"),
    ]
    return table


def missing_messages(bag: Path, contacts: Sequence[str], expected: int, namespace: str = "") -> list[str]:
    """What a lockstep bag lacks: one line per topic recorded fewer than ``expected`` times.

    Every topic is sent once per state in lockstep (the command and controller state once
    per state answered), so a bag of N steps holds N + 1 of each.
    """
    from rosbags.rosbag2 import Reader

    prefix = "/" + namespace.strip("/") + "/" if namespace.strip("/") else "/"
    with Reader(bag) as reader:
        counts: dict[str, int] = {}
        for connection in reader.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
    problems = []
    for topic, _, _ in topic_table(contacts):
        name = topic if topic.startswith("/") else prefix + topic
        if counts.get(name, 0) < expected:
            problems.append(f"{name}: {counts.get(name, 0)} of {expected} messages")
    return problems


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
    ) -> None:
        super().__init__("bracing_recorder", namespace=namespace)
        self.writer = writer
        self.counts: dict[str, int] = {}
        self.received = 0
        self.last_receive = time.monotonic()
        self._connections: dict[Subscription, Connection] = {}
        for topic, msg_type, type_name in topic_table(contacts):
            # Messages are taken directly in ``record`` (no executor: per message it costs more
            # than the write), so the callback is never called.
            sub = self.create_subscription(msg_type, topic, _never_called, RECORD_QOS, raw=True)
            resolved = sub.topic_name
            self._connections[sub] = writer.add_connection(resolved, type_name, typestore=typestore)
            self.counts[resolved] = 0
        self._waiter = SubscriptionWaiter(self, list(self._connections))

    def record(self, timeout_sec: float) -> int:
        """Write every message available now, waiting up to ``timeout_sec``; the count written."""
        taken = self._waiter.take_all(timeout_sec)
        write, connections, counts = self.writer.write, self._connections, self.counts
        for sub, data in taken:
            connection = connections[sub]
            write(connection, cdr_stamp_ns(data), data)
            counts[connection.topic] += 1
        if taken:
            self.received += len(taken)
            self.last_receive = time.monotonic()
        return len(taken)


def _never_called(_: object) -> None:
    raise AssertionError("the recorder takes its messages itself")


def _parse(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="bracing-recorder",
        description="Record the bracing topics to a rosbag2 bag (mcap storage).",
    )
    parser.add_argument("--output", required=True, help="bag directory to create (must not exist)")
    parser.add_argument("--namespace", default="", help="namespace of the recorded nodes")
    parser.add_argument("--contacts", default="", help="comma-separated contact names (contact_wrench/<name>)")
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
        "--drain-idle", type=float, default=0.2, help="on stop, keep receiving until idle this long [s] (default 0.2)"
    )
    parser.add_argument(
        "--drain-timeout", type=float, default=3.0, help="on stop, drain for at most this long [s] (default 3.0)"
    )
    return parser.parse_args(list(argv))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the recorder until SIGINT/SIGTERM; returns the exit code."""
    full = list(sys.argv[1:] if argv is None else argv)
    args = _parse(remove_ros_args(["recorder", *full])[1:])
    contacts = [c.strip() for c in args.contacts.split(",") if c.strip()]
    output = Path(args.output)
    if output.exists():
        print(f"recorder: error: {output} exists already, not overwriting", file=sys.stderr)
        return 2

    stop = {"requested": False, "urgent": False}

    def on_signal(signum: int, frame: FrameType | None) -> None:
        del frame
        if stop["requested"]:
            stop["urgent"] = True  # second signal: skip the drain, still close the bag
        stop["requested"] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    try:
        typestore = bracing_typestore()
    except (FileNotFoundError, OSError) as exc:
        print(f"recorder: error: {exc}", file=sys.stderr)
        return 2

    if args.niceness:
        os.nice(args.niceness)
    rclpy.init(args=["recorder", *full], signal_handler_options=SignalHandlerOptions.NO)
    writer = Writer(output, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    node: Recorder | None = None
    try:
        node = Recorder(writer, typestore, namespace=args.namespace, contacts=contacts)
        print("recorder ready", flush=True)
        while not stop["requested"]:
            if node.record(0.1) and args.batch > 0.0:
                time.sleep(args.batch)  # messages wait in the subscriptions' queues (deep, reliable)
        # Drain what is still in flight: receive until idle for drain_idle (bounded).
        start = time.monotonic()
        node.last_receive = start
        while not stop["urgent"]:
            now = time.monotonic()
            if now - node.last_receive >= args.drain_idle or now - start >= args.drain_timeout:
                break
            node.record(0.05)
    finally:
        writer.close()
        total = node.received if node is not None else 0
        print(f"recorder wrote {total} messages to {output}", flush=True)
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
