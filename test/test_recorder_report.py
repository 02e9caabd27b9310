"""Recorder (rosbag2 over real DDS), bag summary and report.

The ROS tests run the recorder and a synthetic publisher as subprocesses on a random
ROS_DOMAIN_ID with discovery restricted to localhost. The same synthetic step builder
(`make_step`) is used to publish over DDS and to write bags directly for the report
tests, so the expected numbers are known exactly.
"""

from __future__ import annotations

import json
import math
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from array import array
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_helpers import hold_test_domain

ROOT = Path(__file__).resolve().parents[1]
RECORDER_SRC = ROOT / "src" / "bracing_recorder"
try:
    import bracing_recorder  # noqa: F401
except ImportError:  # not built into the workspace yet: use the source tree
    sys.path.insert(0, str(RECORDER_SRC))

from rosbags.highlevel import AnyReader  # noqa: E402

from bracing_analysis.bag import read_series  # noqa: E402
from bracing_analysis.report import main as report_main  # noqa: E402
from bracing_analysis.report import write_report  # noqa: E402
from bracing_analysis.series import BagSeries, ContactSeries  # noqa: E402
from bracing_analysis.summary import SUMMARY_EXTRA_KEYS, SUMMARY_KEYS, compute_summary  # noqa: E402

N_STEPS = 200
DT = 0.02  # 200 steps span 3.98 s, so the t >= 2 s window of the hand error is exercised
CONTACTS = ("elbow", "wrist")
JOINTS = ("joint1", "joint2", "joint3", "joint4")
HAND_OFFSET_EARLY = 0.05  # hand error before t = 2 s (must not count)
HAND_OFFSET = 0.01  # hand error from t = 2 s on
BRACE_OFFSET = 0.002  # brace actual - desired [m], constant
FORCE_DESIRED = 10.0
FORCE_SWING = 0.5  # f_n = f_nd +- 0.5 alternating -> rms error 0.5 N
RESIDUAL_AMPLITUDE = 3e-6
PAPER_URDF = ROOT / "config" / "paper_4link.urdf"


# --------------------------------------------------------------------------- synthetic data


def step_values(k: int) -> dict[str, Any]:
    """Known numbers of step k (pure Python, shared by publisher and assertions)."""
    t = k * DT
    hand_d = (0.0, 1.1 + 0.2 * math.cos(-2 * math.pi * t / 10), 0.6 + 0.2 * math.sin(-2 * math.pi * t / 10))
    off = HAND_OFFSET if t >= 2.0 - 1e-9 else HAND_OFFSET_EARLY
    return {
        "t": t,
        "sec": round(k * DT * 1e9) // 1_000_000_000,
        "nanosec": round(k * DT * 1e9) % 1_000_000_000,
        "position": [0.1 * k + j for j in range(4)],
        "hand_desired": hand_d,
        "hand_actual": (hand_d[0], hand_d[1] + off, hand_d[2]),
        "brace_desired": (0.0, 0.5878, 0.0),
        "brace_actual": (0.0, 0.5878, BRACE_OFFSET),
        "f_n": FORCE_DESIRED + (FORCE_SWING if k % 2 == 0 else -FORCE_SWING),
        "residual": RESIDUAL_AMPLITUDE * math.sin(0.1 * k),
        "energy": 0.1 * k,
        "copper": 0.05 * k,
        "command": [float(k), -float(k), 0.5, 2.0],
    }


def make_step(k: int, contacts: tuple[str, ...] = CONTACTS) -> dict[str, Any]:
    """The rclpy messages of step k, by relative topic name."""
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import Point, Vector3, WrenchStamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    from bracing_msgs.msg import (
        Contacts,
        ContactState,
        ControllerState,
        MotorCommand,
        MotorState,
    )

    v = step_values(k)
    stamp = Time(sec=v["sec"], nanosec=v["nanosec"])
    msgs: dict[str, Any] = {}
    js = JointState()
    js.header.stamp = stamp
    js.name = list(JOINTS)
    js.position = v["position"]
    js.velocity = [0.0, 1.0, 2.0, 3.0]
    js.effort = [float(k)] * 4
    msgs["joint_states"] = js
    for j, name in enumerate(contacts):
        w = WrenchStamped()
        w.header.stamp = stamp
        w.header.frame_id = "world"
        w.wrench.force.z = v["f_n"] + j
        w.wrench.force.y = -0.1 * v["f_n"]
        msgs[f"contact_wrench/{name}"] = w
    cmsg = Contacts()
    cmsg.header.stamp = stamp
    for j, name in enumerate(contacts):
        cmsg.contacts.append(
            ContactState(
                name=name,
                frame=f"{name}_frame",
                active=True,
                position=Point(x=0.0, y=0.5878, z=v["residual"]),
                normal=Vector3(x=0.0, y=0.0, z=1.0),
                normal_force=v["f_n"],
                friction_force=0.1 * v["f_n"],
                slip_velocity=Vector3(x=0.0, y=1e-3 * k, z=0.0),
                residual=v["residual"] * (j + 1),
            )
        )
    msgs["contacts"] = cmsg
    ms = MotorState()
    ms.header.stamp = stamp
    ms.name = list(JOINTS)
    ms.voltage = [1.0, 2.0, 3.0, 4.0]
    ms.current = [0.5] * 4
    ms.power = [0.5, 1.0, 1.5, 2.0]
    ms.energy_consumed = v["energy"]
    ms.energy_net = 0.9 * v["energy"]
    ms.copper_loss = v["copper"]
    msgs["motor_state"] = ms
    msgs["/clock"] = Clock(clock=stamp)
    mc = MotorCommand()
    mc.header.stamp = stamp
    mc.mode = MotorCommand.VOLTAGE
    mc.name = list(JOINTS)
    mc.value = v["command"]
    msgs["motor_command"] = mc
    cs = ControllerState()
    cs.header.stamp = stamp
    cs.hand_desired = Point(x=v["hand_desired"][0], y=v["hand_desired"][1], z=v["hand_desired"][2])
    cs.hand_actual = Point(x=v["hand_actual"][0], y=v["hand_actual"][1], z=v["hand_actual"][2])
    cs.contact_name = list(contacts)
    cs.desired_normal_force = [FORCE_DESIRED] * len(contacts)
    cs.brace_desired = [
        Point(x=v["brace_desired"][0], y=v["brace_desired"][1], z=v["brace_desired"][2]) for _ in contacts
    ]
    cs.brace_actual = [Point(x=v["brace_actual"][0], y=v["brace_actual"][1], z=v["brace_actual"][2]) for _ in contacts]
    cs.command = v["command"]
    cs.compute_time = 1e-4
    msgs["controller_state"] = cs
    return msgs


def write_bag_directly(path: Path, n: int, contacts: tuple[str, ...]) -> None:
    """A bag like the recorder's, written without DDS (for the report tests)."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer

    from bracing_core.typestore import bracing_typestore
    from bracing_recorder.recorder import BAG_VERSION, topic_table

    store = bracing_typestore()
    writer = Writer(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns = {}
    for topic, _, type_name in topic_table(contacts):
        name = topic if topic.startswith("/") else "/" + topic
        conns[topic] = writer.add_connection(name, type_name, typestore=store)
    for k in range(n):
        v = step_values(k)
        ns = v["sec"] * 1_000_000_000 + v["nanosec"]
        for topic, msg in make_step(k, contacts).items():
            writer.write(conns[topic], ns, serialize_message(msg))
    writer.close()


def publisher_main(
    namespace: str, contacts: str, n: int, period: float, wait_go: bool, runs: int = 1, finish_on_go: bool = False
) -> None:
    """Run in a subprocess: publish n synthetic steps of every topic, ``runs`` times over (as a simulator
    reset after each run: robot_description once), each run ended as the simulator ends one: FINISHED on
    run_status (what a recorder with --expect-states waits for).

    Prints "matched" once every topic has a subscriber (then, with `wait_go`, waits for
    a line on stdin before each run), "sent" after each run's last publish and "published" once all is acked.
    With `finish_on_go`, each run's FINISHED waits: "delivered <wall time>" once its messages are acked, then
    a line on stdin, then "finished at <wall time>" as it is said.
    """
    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    from bracing_core.overrides import SIMULATOR
    from bracing_msgs.msg import RunStatus
    from bracing_ros.status import StatusPublisher

    names = tuple(c for c in contacts.split(",") if c)
    rclpy.init()
    node = rclpy.create_node("synthetic_publisher", namespace=namespace)
    status = StatusPublisher(rclpy.create_node(SIMULATOR, namespace=namespace))
    # As the nodes publish: reliable and transient-local (the recorder requests transient-local).
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    pubs = {topic: node.create_publisher(type(msg), topic, qos) for topic, msg in make_step(0, names).items()}
    # As the simulator: the URDF, latched, before the first state (the recorder derives /tf from it).
    from std_msgs.msg import String

    description = node.create_publisher(String, "robot_description", qos)
    description.publish(String(data=PAPER_URDF.read_text(encoding="utf-8")))
    deadline = time.monotonic() + 15.0
    while any(p.get_subscription_count() == 0 for p in pubs.values()):
        if time.monotonic() > deadline:
            print("publisher: recorder not discovered", flush=True)
            sys.exit(3)
        rclpy.spin_once(node, timeout_sec=0.02)
    description.wait_for_all_acked(rclpy.duration.Duration(seconds=15.0))  # received, not only matched
    print("matched", flush=True)
    for _ in range(runs):
        if wait_go:
            sys.stdin.readline()
        for k in range(n):
            for topic, msg in make_step(k, names).items():
                pubs[topic].publish(msg)
            if period > 0:
                time.sleep(period)
        if finish_on_go:
            for p in pubs.values():
                p.wait_for_all_acked(rclpy.duration.Duration(seconds=15.0))
            print("delivered", flush=True)
            sys.stdin.readline()
            print(f"finished at {time.time():.6f}", flush=True)
        status.say(RunStatus.FINISHED, (n - 1) * DT)
        print("sent", flush=True)
    for p in pubs.values():
        p.wait_for_all_acked(rclpy.duration.Duration(seconds=5.0))
    status.flush()
    print("published", flush=True)
    node.destroy_node()
    rclpy.shutdown()


def batch_publisher_main(namespace: str, contacts: str, n: int, sent_file: str) -> None:
    """Run in a subprocess: as the nodes do with record_batch 10, publish n synthetic steps on their
    topics and in batches (bracing_ros.record_batch); between them, a batch that cannot be unpacked
    (from another node) and one this node's recorder never gets (a gap in its sequence). Prints
    "matched" once the recorder subscribes to the batches and "published" once all is acked; the
    bytes of the steps in batches that were sent go to ``sent_file`` (JSON, hex by topic)."""
    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from bracing_msgs.msg import RecordBatch
    from bracing_ros.qos import RECORD_BATCH_QOS
    from bracing_ros.record_batch import RECORD_BATCH_TOPIC, RecordBatchPublisher

    names = tuple(c for c in contacts.split(",") if c)
    rclpy.init()
    node = rclpy.create_node("synthetic_publisher", namespace=namespace)
    reliable, latched = ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=reliable, durability=latched)
    pubs = {topic: node.create_publisher(type(msg), topic, qos) for topic, msg in make_step(0, names).items()}
    description = node.create_publisher(String, "robot_description", qos)
    description.publish(String(data=PAPER_URDF.read_text("utf-8")))
    batches = RecordBatchPublisher(node, list(pubs.values()), 10)
    intruder = node.create_publisher(RecordBatch, RECORD_BATCH_TOPIC, RECORD_BATCH_QOS)
    deadline = time.monotonic() + 15.0
    # robot_description too, as the simulator waits for it: a recorder stopped before it matched the latched
    # description derives no /tf (its subscriptions, more with the target verdicts, match one by one)
    readers = (batches.publisher, intruder, description)
    while any(pub.get_subscription_count() == 0 for pub in readers):
        if time.monotonic() > deadline:
            print("publisher: recorder not discovered", flush=True)
            sys.exit(3)
        rclpy.spin_once(node, timeout_sec=0.02)
    # Matched here is not received there: the recorder's reader may match this writer later (its
    # participant learns of it in turn), and only then asks for the latched description.
    description.wait_for_all_acked(rclpy.duration.Duration(seconds=15.0))
    print("matched", flush=True)
    broken = RecordBatch(node="/intruder", sequence=0, topics=["/joint_states"])
    broken.topic_of, broken.end, broken.data = array("H", [0]), array("I", [8]), array("B", b"four")
    sent: dict[str, list[str]] = {topic: [] for topic in pubs}
    for k in range(n):
        if k == 10:
            intruder.publish(broken)  # its bytes end after its data: left out whole
            batches._packer.sequence += 1  # states 10-19: a batch the recorder never gets
        lost = 10 <= k < 20
        for topic, msg in make_step(k, names).items():
            data = serialize_message(msg)
            if lost:
                pubs[topic].publish(data)
            else:
                batches.publish(pubs[topic], data)
                sent[topic].append(data.hex())
        if not lost:
            batches.state_done()
    batches.close(timeout_sec=5.0)
    Path(sent_file).write_text(json.dumps(sent))
    print("published", flush=True)
    node.destroy_node()
    rclpy.shutdown()


# --------------------------------------------------------------------------- process helpers


def ros_env() -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(hold_test_domain())  # held until the test ends
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONPATH"] = os.pathsep.join(
        [str(RECORDER_SRC), str(Path(__file__).resolve().parent), env.get("PYTHONPATH", "")]
    )
    env["PYTHONUNBUFFERED"] = "1"
    return env


class Proc:
    """A subprocess whose stdout lines are collected by a reader thread."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.popen = subprocess.Popen(
            args, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.stdout: list[str] = []
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            self.stdout.append(line)
            self.lines.put(line.rstrip("\n"))

    def wait_line(self, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            try:
                if self.lines.get(timeout=min(left, 0.1)) == text:
                    return
            except queue.Empty:
                if self.popen.poll() is not None and self.lines.empty():
                    break
        err = self.popen.stderr.read() if self.popen.poll() is not None and self.popen.stderr else ""
        pytest.fail(f"no line {text!r} within {timeout} s from {self.popen.args}: {err}")

    def finish(self, timeout: float) -> tuple[int, str]:
        try:
            self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
            pytest.fail(f"{self.popen.args} did not exit within {timeout} s")
        self._thread.join(timeout=5.0)
        err = self.popen.stderr.read() if self.popen.stderr else ""
        return self.popen.returncode, err

    def kill(self) -> None:
        if self.popen.poll() is None:
            self.popen.kill()
            self.popen.wait()


@pytest.fixture
def procs() -> Iterator[list[Proc]]:
    started: list[Proc] = []
    yield started
    for p in started:
        p.kill()


def start_recorder(
    procs: list[Proc], env: dict[str, str], bag: Path, namespace: str, contacts: tuple[str, ...], *extra: str
) -> Proc:
    args = [sys.executable, "-m", "bracing_recorder.command", "--output", str(bag), "--contacts", ",".join(contacts)]
    args += extra
    if namespace:
        args += ["--namespace", namespace]
    rec = Proc(args, env)
    procs.append(rec)
    rec.wait_line("recorder ready", timeout=15.0)
    return rec


FAST_HEARTBEAT_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <data_writer profile_name="fast_heartbeat_writer" is_default_profile="true">
    <times>
      <heartbeatPeriod><sec>0</sec><nanosec>20000000</nanosec></heartbeatPeriod>
    </times>
  </data_writer>
</profiles>
"""


def start_publisher(
    procs: list[Proc],
    env: dict[str, str],
    tmp_path: Path,
    namespace: str,
    contacts: tuple[str, ...],
    n: int,
    period: float,
    wait_go: bool = False,
    runs: int = 1,
    finish_on_go: bool = False,
) -> Proc:
    # Fast DDS's default 3 s writer heartbeat would delay any retransmission (and the
    # final acknowledgements) by up to 3 s; 20 ms keeps delivery prompt and the test fast.
    profile = tmp_path / "fastdds_publisher.xml"
    profile.write_text(FAST_HEARTBEAT_PROFILE)
    env = {**env, "FASTRTPS_DEFAULT_PROFILES_FILE": str(profile)}
    code = (
        "import test_recorder_report as t; "
        f"t.publisher_main({namespace!r}, {','.join(contacts)!r}, {n}, {period}, {wait_go}, {runs}, {finish_on_go})"
    )
    pub = Proc([sys.executable, "-c", code], env)
    procs.append(pub)
    return pub


def read_bag(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """topic -> [(bag timestamp, message)], decoded with the bag's own definitions only."""
    out: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([bag]) as reader:  # no default typestore: definitions from the bag
        for conn in reader.connections:
            out.setdefault(conn.topic, [])
        for conn, stamp, raw in reader.messages():
            out[conn.topic].append((stamp, reader.deserialize(raw, conn.msgtype)))
    return out


def expected_topics(namespace: str, contacts: tuple[str, ...]) -> set[str]:
    """Every recorded topic, and what the recorder derives: /tf, /tf_static, contact_markers."""
    prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
    rel = ["joint_states", "contacts", "motor_state", "motor_command", "controller_state", "robot_description"]
    rel += [f"contact_wrench/{c}" for c in contacts]
    rel += ["contact_markers"] if contacts else []
    return {f"{prefix}/{t}" for t in rel} | {"/clock", "/tf", "/tf_static"}


ONCE = ("robot_description", "/tf_static")  # one message per run, not per state


# --------------------------------------------------------------------------- recorder tests


def test_recorder_records_every_topic_exactly(tmp_path: Path, procs: list[Proc]) -> None:
    env = ros_env()
    bag = tmp_path / "run" / "bag"
    rec = start_recorder(procs, env, bag, "", CONTACTS)
    pub = start_publisher(procs, env, tmp_path, "", CONTACTS, N_STEPS, period=0.0, wait_go=True)
    pub.wait_line("matched", timeout=20.0)
    # Freeze the recorder while everything is published, then ask it to stop and let it
    # run again: every message is still pending, so only the drain can record them.
    rec.popen.send_signal(signal.SIGSTOP)
    try:
        assert pub.popen.stdin is not None
        pub.popen.stdin.write("go\n")
        pub.popen.stdin.flush()
        pub.wait_line("sent", timeout=20.0)
        time.sleep(0.2)
        rec.popen.send_signal(signal.SIGINT)
    finally:
        rec.popen.send_signal(signal.SIGCONT)
    rc, err = rec.finish(timeout=15.0)
    assert rc == 0, err
    assert f"recorder wrote {N_STEPS * 8 + 1} messages" in "".join(rec.stdout)  # + robot_description
    assert f"recorder derived {2 * N_STEPS + 1} messages" in "".join(rec.stdout)  # /tf and markers per state
    pub.wait_line("published", timeout=10.0)  # the publisher saw every message acked
    assert pub.finish(timeout=10.0)[0] == 0

    meta = (bag / "metadata.yaml").read_text()
    assert "storage_identifier: mcap" in meta
    assert list(bag.glob("*.mcap"))

    data = read_bag(bag)
    assert set(data) == expected_topics("", CONTACTS)
    for topic, msgs in data.items():
        assert len(msgs) == (1 if topic.endswith(ONCE) else N_STEPS), topic
    assert sorted(s for s, _ in data["/tf"]) == sorted(s for s, _ in data["/joint_states"])

    for k, (stamp, js) in enumerate(sorted(data["/joint_states"], key=lambda x: x[0])):
        v = step_values(k)
        assert stamp == v["sec"] * 1_000_000_000 + v["nanosec"]  # bag time = header stamp
        assert list(js.name) == list(JOINTS)
        assert np.array_equal(js.position, v["position"])
        assert np.array_equal(js.velocity, [0.0, 1.0, 2.0, 3.0])
    for j, name in enumerate(CONTACTS):
        forces = sorted((s, m.wrench.force.z) for s, m in data[f"/contact_wrench/{name}"])
        assert [f for _, f in forces] == [step_values(k)["f_n"] + j for k in range(N_STEPS)]
        assert all(m.header.frame_id == "world" for _, m in data[f"/contact_wrench/{name}"])
    clocks = sorted(s for s, _ in data["/clock"])
    assert clocks == sorted(s for s, _ in data["/joint_states"])
    assert all(s == m.clock.sec * 1_000_000_000 + m.clock.nanosec for s, m in data["/clock"])
    stamp0, c0 = min(data["/contacts"], key=lambda x: x[0])
    assert stamp0 == 0
    assert [c.name for c in c0.contacts] == list(CONTACTS)
    assert c0.contacts[0].active and c0.contacts[0].frame == "elbow_frame"
    assert c0.contacts[1].normal.z == 1.0
    last_cmd = max(data["/motor_command"], key=lambda x: x[0])[1]
    assert last_cmd.mode == 0 and list(last_cmd.value) == step_values(N_STEPS - 1)["command"]
    last_ms = max(data["/motor_state"], key=lambda x: x[0])[1]
    assert last_ms.energy_consumed == pytest.approx(step_values(N_STEPS - 1)["energy"])
    assert list(last_ms.power) == [0.5, 1.0, 1.5, 2.0]
    cs = max(data["/controller_state"], key=lambda x: x[0])[1]
    assert list(cs.contact_name) == list(CONTACTS)
    assert cs.brace_actual[1].z == BRACE_OFFSET
    assert cs.hand_actual.y == step_values(N_STEPS - 1)["hand_actual"][1]

    # The summary of the recorded run has the designed errors.
    summary = compute_summary(read_series(bag), wall_time_s=2.0)
    assert summary["hand_rms_error_m"] == pytest.approx(HAND_OFFSET, abs=1e-12)
    assert summary["hand_max_error_m"] == pytest.approx(HAND_OFFSET, abs=1e-12)
    assert summary["brace_rms_error_m"] == pytest.approx(BRACE_OFFSET, abs=1e-12)
    assert summary["normal_force_rms_error_n"] == pytest.approx(FORCE_SWING, abs=1e-12)
    assert summary["sim_time_s"] == pytest.approx((N_STEPS - 1) * DT)
    assert summary["real_time_factor"] == pytest.approx((N_STEPS - 1) * DT / 2.0)


def test_recorder_closes_the_bag_once_it_has_every_message(tmp_path: Path, procs: list[Proc]) -> None:
    """--expect-states N (bracing-pair's lockstep runs): no signal and no drain; the recorder
    closes the bag as soon as every topic has N messages, and exits."""
    env = ros_env()
    bag = tmp_path / "run" / "bag"
    rec = start_recorder(procs, env, bag, "", CONTACTS, "--expect-states", str(N_STEPS))
    pub = start_publisher(procs, env, tmp_path, "", CONTACTS, N_STEPS, period=0.0)
    rc, err = rec.finish(timeout=30.0)
    assert rc == 0, err
    assert any(line.startswith("recorder closed the bag at ") for line in rec.stdout)
    assert pub.finish(timeout=15.0)[0] == 0
    data = read_bag(bag)
    assert set(data) == expected_topics("", CONTACTS)
    for topic, msgs in data.items():
        assert len(msgs) == (1 if topic.endswith(ONCE) else N_STEPS), topic


def test_recorder_with_every_message_waits_for_the_simulators_finished(tmp_path: Path, procs: list[Proc]) -> None:
    """--expect-states N: every message in is not yet the end of the run (the simulator's last warnings
    come after its last state, and a reader of run_status may match late and hear nothing before);
    the bag closes only after the simulator's FINISHED, held back here until every message was delivered."""
    env = ros_env()
    bag = tmp_path / "run" / "bag"
    rec = start_recorder(procs, env, bag, "", CONTACTS, "--expect-states", str(N_STEPS))
    pub = start_publisher(procs, env, tmp_path, "", CONTACTS, N_STEPS, period=0.0, finish_on_go=True)
    pub.wait_line("delivered", timeout=30.0)
    time.sleep(0.5)  # the recorder takes what was delivered (it polls every 0.1 s): without the rule it closes now
    assert pub.popen.stdin is not None
    pub.popen.stdin.write("go\n")
    pub.popen.stdin.flush()
    rc, err = rec.finish(timeout=30.0)
    assert rc == 0, err
    assert pub.finish(timeout=15.0)[0] == 0
    said = float(next(line for line in pub.stdout if line.startswith("finished at "))[12:])
    closed = float(next(line for line in rec.stdout if line.startswith("recorder closed the bag at "))[27:])
    assert closed > said
    data = read_bag(bag)
    assert all(len(msgs) == (1 if topic.endswith(ONCE) else N_STEPS) for topic, msgs in data.items())


def test_recorder_from_batches_writes_each_message_under_its_topic(tmp_path: Path, procs: list[Proc]) -> None:
    """--from-batches: the bag holds what subscribing to each topic would have given, message for
    message and byte for byte; a batch that cannot be unpacked is left out with an error, and a
    node's lost batch is reported."""
    env = ros_env()
    bag = tmp_path / "run" / "bag"
    n, sent_file = 40, tmp_path / "sent.json"
    rec = start_recorder(procs, env, bag, "", CONTACTS, "--from-batches")
    code = f"import test_recorder_report as t; t.batch_publisher_main('', {','.join(CONTACTS)!r}, {n}, '{sent_file}')"
    pub = Proc([sys.executable, "-c", code], env)
    procs.append(pub)
    pub.wait_line("published", timeout=30.0)
    rec.popen.send_signal(signal.SIGINT)
    rc, err = rec.finish(timeout=15.0)
    assert rc == 0, err
    assert "a record_batch from /intruder left out: message 0: its bytes end at 8" in err
    assert "1 batch(es) from /synthetic_publisher lost (sequence 2)" in err
    kept = [step_values(k) for k in range(n) if not 10 <= k < 20]  # batch 1 (states 10-19) was never sent
    data = read_bag(bag)
    assert set(data) == expected_topics("", CONTACTS)
    raw: dict[str, list[tuple[int, str]]] = {}
    with AnyReader([bag]) as reader:
        for conn, stamp, message in reader.messages():
            raw.setdefault(conn.topic, []).append((stamp, bytes(message).hex()))
    for topic, sent in json.loads(sent_file.read_text()).items():
        name = topic if topic.startswith("/") else "/" + topic
        assert [message for _, message in raw[name]] == sent, name
        assert [stamp for stamp, _ in raw[name]] == [v["sec"] * 1_000_000_000 + v["nanosec"] for v in kept], name
    assert len(data["/tf"]) == len(kept)  # the scene from the batches' joint_states


@pytest.mark.parametrize(("sig", "publisher_keeps_going"), [(signal.SIGINT, True), (signal.SIGTERM, False)])
def test_recorder_stopped_mid_stream_leaves_readable_bag(
    tmp_path: Path, procs: list[Proc], sig: signal.Signals, publisher_keeps_going: bool
) -> None:
    env = ros_env()
    bag = tmp_path / "bag"
    contacts = ("elbow",)
    rec = start_recorder(procs, env, bag, "robot1", contacts, "--drain-timeout", "3")
    total = 100000  # far more than gets sent before the stop
    pub = start_publisher(procs, env, tmp_path, "robot1", contacts, total, period=0.001)
    pub.wait_line("matched", timeout=15.0)
    time.sleep(0.5)
    assert pub.popen.poll() is None
    rec.popen.send_signal(sig)
    if not publisher_keeps_going:  # like bracing-pair: the nodes stop with the recorder
        pub.kill()
    rc, err = rec.finish(timeout=15.0)  # a continuing stream is drained for <= 3 s
    assert rc == 0, err
    if publisher_keeps_going:
        assert pub.popen.poll() is None
        pub.kill()

    data = read_bag(bag)
    assert set(data) == expected_topics("robot1", contacts)
    stamps = sorted(s for s, _ in data["/robot1/joint_states"])
    assert 10 < len(stamps) < total
    assert stamps[0] == 0 and len(set(stamps)) == len(stamps)
    if publisher_keeps_going:
        # Reliable, in-order delivery: the recording is an unbroken prefix of the stream.
        expected = [step_values(k)["sec"] * 1_000_000_000 + step_values(k)["nanosec"] for k in range(len(stamps))]
        assert stamps == expected
    for _, msg in data["/robot1/controller_state"]:
        assert list(msg.contact_name) == ["elbow"]


def test_recorder_refuses_existing_output(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    res = subprocess.run(
        [sys.executable, "-m", "bracing_recorder.command", "--output", str(bag)],
        env=ros_env(),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert res.returncode == 2
    assert "exists already" in res.stderr
    assert list(bag.iterdir()) == []


# --------------------------------------------------------------------------- summary tests


def _series(n: int = 401, dt: float = 0.01) -> BagSeries:
    t = np.arange(n) * dt
    hand_d = np.stack([np.zeros(n), 1.1 + 0.2 * np.cos(t), 0.6 + 0.2 * np.sin(t)], axis=1)
    s = BagSeries(joint_t=t.copy(), t=t.copy(), hand_desired=hand_d, hand_actual=hand_d + np.array([0.0, 0.0, 0.01]))
    s.motor_t = t.copy()
    s.energy_consumed = 2.0 * t
    s.energy_net = 1.5 * t
    s.copper_loss = 0.5 * t
    return s


def test_summary_constant_hand_offset_and_no_contacts() -> None:
    s = _series()
    s.hand_actual[t_early := s.t < 2.0] += np.array([0.0, 1.0, 0.0])  # huge, but before 2 s
    assert t_early.any()
    out = compute_summary(s)
    assert list(out) == [*SUMMARY_KEYS, *SUMMARY_EXTRA_KEYS]
    assert out["hand_rms_error_m"] == pytest.approx(0.01, abs=1e-12)
    assert out["hand_max_error_m"] == pytest.approx(0.01, abs=1e-12)
    assert out["brace_rms_error_m"] is None  # no contacts: not applicable (null), not 0
    assert out["normal_force_rms_error_n"] is None
    assert out["constraint_residual_max_m"] is None
    assert out["energy_consumed_j"] == pytest.approx(8.0)
    assert out["copper_loss_j"] == pytest.approx(2.0)
    assert out["sim_time_s"] == pytest.approx(4.0)
    assert out["wall_time_s"] is None and out["real_time_factor"] is None
    json.dumps(out, allow_nan=False)


def test_summary_contacts_errors_and_rtf() -> None:
    s = _series(n=101, dt=0.05)
    n = s.t.size
    # 3-4-5 triangle: brace error 0.005 everywhere.
    cs = ContactSeries(name="elbow", t=s.t.copy(), t_ctrl=s.t.copy())
    cs.brace_desired = np.zeros((n, 3))
    cs.brace_actual = np.tile([0.0, 0.003, 0.004], (n, 1))
    cs.normal_force = 10.0 + np.where(np.arange(n) % 2 == 0, 2.0, -2.0)
    cs.normal_force_desired = np.full(n, 10.0)
    cs.t_matched = s.t.copy()
    cs.normal_force_error = cs.normal_force - 10.0
    cs.residual = np.linspace(-2e-6, 1e-6, n)
    s.contacts["elbow"] = cs
    out = compute_summary(s, wall_time_s=2.5)
    assert out["brace_rms_error_m"] == pytest.approx(0.005)
    assert out["normal_force_rms_error_n"] == pytest.approx(2.0)
    assert out["constraint_residual_max_m"] == pytest.approx(2e-6)
    assert out["sim_time_s"] == pytest.approx(5.0)
    assert out["wall_time_s"] == 2.5
    assert out["real_time_factor"] == pytest.approx(2.0)


def test_read_series_matches_force_by_stamp(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    write_bag_directly(bag, N_STEPS, ("elbow",))
    s = read_series(bag)
    assert s.t0_ns == 0
    assert np.allclose(s.joint_t, np.arange(N_STEPS) * DT)
    el = s.contacts["elbow"]
    assert el.t_matched.size == N_STEPS
    assert np.allclose(np.abs(el.normal_force_error), FORCE_SWING)
    assert np.allclose(el.normal_force_desired, FORCE_DESIRED)
    assert s.hand_actual.shape == (N_STEPS, 3)
    expected_res = max(abs(step_values(k)["residual"]) for k in range(N_STEPS))
    out = compute_summary(s)
    assert out["constraint_residual_max_m"] == pytest.approx(expected_res)
    assert out["energy_consumed_j"] == pytest.approx(step_values(N_STEPS - 1)["energy"])
    assert out["copper_loss_j"] == pytest.approx(step_values(N_STEPS - 1)["copper"])


# --------------------------------------------------------------------------- report tests

# The synthetic brace point stays put but for its constant offset along z: its plot is brace_z.
PLOTS = ("hand_y.png", "hand_z.png", "brace_z.png", "normal_force.png", "energy.png")


def test_report_writes_plots_and_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "run" / "bag"
    write_bag_directly(bag, N_STEPS, CONTACTS)
    (tmp_path / "run" / "summary.json").write_text(json.dumps({"wall_time_s": 1.99}))
    assert report_main([str(bag)]) == 0
    run = tmp_path / "run"
    for name in PLOTS:
        png = run / name
        assert png.stat().st_size > 5000, name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((run / "summary.json").read_text())
    assert list(summary) == [*SUMMARY_KEYS, *SUMMARY_EXTRA_KEYS]
    assert summary["wall_time_s"] == 1.99  # kept from the existing summary.json
    assert summary["real_time_factor"] == pytest.approx((N_STEPS - 1) * DT / 1.99)
    assert summary["hand_rms_error_m"] == pytest.approx(HAND_OFFSET, abs=1e-12)
    assert summary["brace_rms_error_m"] == pytest.approx(BRACE_OFFSET, abs=1e-12)
    assert "hand_rms_error_m" in capsys.readouterr().out


def test_report_without_contacts_skips_brace_plots(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    write_bag_directly(bag, 150, ())
    out = tmp_path / "figs"
    summary = write_report(bag, out)
    written = sorted(p.name for p in out.glob("*.png"))
    assert written == ["energy.png", "hand_y.png", "hand_z.png"]
    assert summary["brace_rms_error_m"] is None
    assert summary["normal_force_rms_error_n"] is None
    assert summary["wall_time_s"] is None
    assert json.loads((out / "summary.json").read_text()) == summary


def test_report_missing_or_broken_bag_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert report_main([str(tmp_path / "nope" / "bag")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bag not found" in err
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "metadata.yaml").write_text("rosbag2_bagfile_information: {version: 8}\n")
    assert report_main([str(broken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("bracing-report: error: cannot read bag") and err.count("\n") == 1
    assert not list(tmp_path.glob("*.png"))


def test_missing_messages_names_every_short_topic(tmp_path: Path) -> None:
    """bracing-pair's completeness check: a lockstep bag of N steps holds N + 1 of every topic
    (and of /tf and contact_markers), robot_description and /tf_static once."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from bracing_core.typestore import bracing_typestore
    from bracing_recorder.recorder import BAG_VERSION, expected_counts, missing_messages

    store, expected = bracing_typestore(), 5
    counts = expected_counts(["elbow"], expected)
    assert counts["/robot_description"] == counts["/tf_static"] == 1
    assert counts["/tf"] == counts["/contact_markers"] == counts["/joint_states"] == expected
    assert "/contact_markers" not in expected_counts([], expected)
    bag = tmp_path / "bag"
    written = {"/joint_states": 2, "/contact_wrench/elbow": 0, "/tf": 4, "/tf_static": 0}
    with Writer(bag, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        for name, wanted in counts.items():
            connection = writer.add_connection(name, "std_msgs/msg/Empty", typestore=store)
            for k in range(written.get(name, wanted)):
                writer.write(connection, k, b"\x00\x01\x00\x00" + bytes(8))
    assert missing_messages(bag, ["elbow"], expected) == [
        "/joint_states: 2 of 5 messages",
        "/contact_wrench/elbow: 0 of 5 messages",
        "/tf_static: 0 of 1 messages",
        "/tf: 4 of 5 messages",
    ]
    assert missing_messages(bag, ["elbow"], 2) == [
        "/contact_wrench/elbow: 0 of 2 messages",
        "/tf_static: 0 of 1 messages",
    ]
