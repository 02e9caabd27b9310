"""Property-based fuzzing (hypothesis) of both nodes over DDS.

Each node runs as its own process in a domain this test holds; the test process is a real
rclpy participant that sends it arbitrary bytes and well-formed messages with arbitrary
names, lengths, values, modes and stamps, interleaved with valid traffic. Properties: the
node stays alive, everything it publishes is finite, and it steps (simulator) or answers
(controller) as soon as valid input resumes. Seeded (derandomize) and bounded (a fixed
number of examples, every wait with a timeout).
"""

from __future__ import annotations

import math
import os
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import WrenchStamped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lockstep_driver import JOINTS, known_command
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from ros_helpers import (
    CONTROLLER_PATHS,
    PATH_LINES,
    SIMULATOR_PATH_LINES,
    SIMULATOR_PATHS,
    isolated_env,
    node_argv,
    params_file,
    start,
)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from bracing_bringup.domains import hold_domain
from bracing_controller.rcl_path import PATH_ENV
from bracing_msgs.msg import Contacts, ControllerState, MotorCommand, MotorState
from bracing_ros.qos import STREAM_QOS
from bracing_sim.rcl_path import PATH_ENV as SIMULATOR_PATH_ENV

EXAMPLES = int(os.environ.get("BRACING_FUZZ_EXAMPLES", "200"))
FUZZ_SETTINGS = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,  # the same examples on every run
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
CDR_LE = b"\x00\x01\x00\x00"
INT32 = st.integers(-(2**31), 2**31 - 1)
UINT32 = st.integers(0, 2**32 - 1)
FLOATS = st.floats(allow_nan=True, allow_infinity=True)
NAMES = st.lists(
    st.one_of(st.sampled_from(JOINTS), st.text(st.characters(blacklist_characters="\x00"), max_size=8)), max_size=6
)
# At least one byte: an empty serialized payload jams the *sending* Fast DDS writer (nothing it
# sends afterwards arrives anywhere); it never reaches a node, so it is not the nodes' to handle.
RAW = st.one_of(st.binary(min_size=1, max_size=300), st.binary(max_size=300).map(lambda b: CDR_LE + b))


def finite(values: Any) -> bool:
    return bool(np.isfinite(np.asarray(values, dtype=float)).all())


@dataclass
class Peer:
    """This test process as a ROS participant in the node's domain."""

    context: Context
    node: Node
    executor: SingleThreadedExecutor
    received: dict[str, list[Any]] = field(default_factory=dict)
    non_finite: list[str] = field(default_factory=list)

    def listen(self, msg_type: type, topic: str, numbers: Any) -> None:
        self.received[topic] = []

        def on_message(msg: Any) -> None:
            self.received[topic].append(msg)
            if not finite(numbers(msg)):
                self.non_finite.append(f"{topic}: {msg}")

        self.node.create_subscription(msg_type, topic, on_message, STREAM_QOS)

    def spin_until(self, condition: Any, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.01)
        return True


def start_peer(env: dict[str, str], name: str) -> Peer:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    context = Context()
    rclpy.init(context=context, domain_id=int(env["ROS_DOMAIN_ID"]))
    node = rclpy.create_node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    return Peer(context, node, executor)


def close_peer(peer: Peer) -> None:
    peer.executor.shutdown()
    peer.node.destroy_node()
    rclpy.try_shutdown(context=peer.context)


def stop(peer: Peer, process: subprocess.Popen[str]) -> str:
    close_peer(peer)
    if process.poll() is None:
        process.terminate()
    return process.communicate(timeout=30)[0]


# ------------------------------------------------------------------------------ simulator


@dataclass
class SimHarness:
    peer: Peer
    process: subprocess.Popen[str]
    command_pub: Any

    def latest_stamp(self) -> int:
        state = self.peer.received["joint_states"][-1]
        return int(state.header.stamp.sec) * 10**9 + int(state.header.stamp.nanosec)


@pytest.fixture(scope="module", params=SIMULATOR_PATHS)
def simulator(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> Iterator[SimHarness]:
    """The simulator taking motor_command on each path (bracing_sim.rcl_path)."""
    # A domain held for the fixture's life (the per-test release of ros_helpers would end it early).
    with hold_domain() as domain:
        env = isolated_env(domain.domain_id, **{SIMULATOR_PATH_ENV: request.param})
        yield from _simulator(tmp_path_factory, env, request.param)


def _simulator(
    tmp_path_factory: pytest.TempPathFactory, domain_env: dict[str, str], path: str = "rcl"
) -> Iterator[SimHarness]:
    tmp = tmp_path_factory.mktemp("fuzz-sim")
    overrides = {"duration": 0.0, "command_timeout": 0.05, "watchdog_policy": "zero"}
    process = start(node_argv("bracing_sim.node", params_file(tmp, "bracing_simulator", overrides)), domain_env)
    peer = start_peer(domain_env, "fuzz_simulator_peer")
    peer.listen(JointState, "joint_states", lambda m: [*m.position, *m.velocity, *m.effort])
    peer.listen(MotorState, "motor_state", lambda m: [*m.voltage, *m.current, *m.power, m.energy_consumed])
    peer.listen(Contacts, "contacts", lambda m: [x for c in m.contacts for x in (c.normal_force, c.residual)])
    peer.listen(WrenchStamped, "contact_wrench/elbow", lambda m: [m.wrench.force.x, m.wrench.force.y])
    peer.listen(Clock, "/clock", lambda m: [m.clock.sec])
    command_pub = peer.node.create_publisher(MotorCommand, "motor_command", STREAM_QOS)
    harness = SimHarness(peer, process, command_pub)
    assert peer.spin_until(lambda: peer.received["joint_states"], 60.0), "the simulator did not start"
    yield harness
    log = stop(peer, process)
    assert "Traceback" not in log, log[-3000:]
    assert SIMULATOR_PATH_LINES[path] in log, log[-3000:]


def command(names: list[str], values: list[float], mode: int, stamp_ns: int) -> MotorCommand:
    msg = MotorCommand(mode=mode, name=names, value=values)
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_ns // 10**9, stamp_ns % 10**9
    return msg


STAMPS = st.one_of(st.sampled_from(["current", "stale", "future"]), st.tuples(INT32, UINT32))
WELL_FORMED_COMMAND = st.tuples(NAMES, st.lists(FLOATS, max_size=6), st.integers(0, 255), STAMPS)
# The ones the simulator accepts up to their values: every joint by name, the configured mode, its stamp.
VALID_BUT_FOR_VALUES = st.tuples(
    st.permutations(JOINTS), st.lists(FLOATS, min_size=4, max_size=4), st.just(0), st.just("current")
)
SIM_EVENT = st.one_of(RAW, WELL_FORMED_COMMAND, VALID_BUT_FOR_VALUES)


@FUZZ_SETTINGS
@given(events=st.lists(SIM_EVENT, min_size=1, max_size=6))
def test_simulator_survives_fuzzed_commands(simulator: SimHarness, events: list[Any]) -> None:
    peer, states = simulator.peer, simulator.peer.received["joint_states"]
    now = simulator.latest_stamp()
    for event in events:
        if isinstance(event, bytes):
            simulator.command_pub.publish(event)
            continue
        names, values, mode, stamp = event
        stamp_ns = {"current": now, "stale": now - 10**6, "future": now + 10**6}.get(stamp, None)
        if stamp_ns is None:
            sec, nanosec = stamp
            stamp_ns = sec * 10**9 + nanosec
        msg = MotorCommand(mode=mode, name=list(names), value=[float(v) for v in values])
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec_nanosec(stamp_ns)
        simulator.command_pub.publish(msg)
    # Valid traffic resumes: the simulator steps past the state it was waiting on.
    simulator.command_pub.publish(command(JOINTS, known_command(0), MotorCommand.VOLTAGE, now))
    assert peer.spin_until(lambda: simulator.latest_stamp() > now, 10.0), "the simulator did not step again"
    assert simulator.process.poll() is None, "the simulator died"
    assert not peer.non_finite, peer.non_finite[:3]
    assert len(states) >= 2


def sec_nanosec(stamp_ns: int) -> tuple[int, int]:
    """(sec, nanosec) of a builtin_interfaces/Time, clamped into its int32 seconds."""
    sec, nanosec = divmod(stamp_ns, 10**9)
    if not -(2**31) <= sec < 2**31:
        return (2**31 - 1 if sec > 0 else -(2**31)), nanosec
    return sec, nanosec


# ------------------------------------------------------------------------------ controller


@dataclass
class ControllerHarness:
    peer: Peer
    process: subprocess.Popen[str]
    state_pub: Any
    next_stamp_ms: int = 1

    def answered(self, stamp_ns: int) -> bool:
        return any(
            int(m.header.stamp.sec) * 10**9 + int(m.header.stamp.nanosec) == stamp_ns
            for m in self.peer.received["motor_command"][-20:]
        )


@pytest.fixture(scope="module", params=CONTROLLER_PATHS)
def controller(request: pytest.FixtureRequest) -> Iterator[ControllerHarness]:
    """The controller node on each of its per-state paths (the C++ one on rcl, the Python one)."""
    with hold_domain() as domain:
        yield from _controller(isolated_env(domain.domain_id, **{PATH_ENV: request.param}), request.param)


def _controller(domain_env: dict[str, str], path: str = "rcl") -> Iterator[ControllerHarness]:
    process = start(node_argv("bracing_controller.node"), domain_env)
    peer = start_peer(domain_env, "fuzz_controller_peer")
    peer.listen(MotorCommand, "motor_command", lambda m: m.value)
    peer.listen(
        ControllerState,
        "controller_state",
        lambda m: [*m.command, m.hand_actual.x, m.hand_actual.y, m.hand_actual.z, *m.desired_normal_force],
    )
    state_pub = peer.node.create_publisher(JointState, "joint_states", STREAM_QOS)
    assert peer.spin_until(lambda: state_pub.get_subscription_count() > 0, 60.0), "the controller did not start"
    yield ControllerHarness(peer, process, state_pub)
    log = stop(peer, process)
    assert "Traceback" not in log, log[-3000:]
    assert PATH_LINES[path] in log, log[-3000:]


START = (np.array([-0.2, -0.6, 0.8, -0.4]) * math.pi).tolist()
JOINT_STATE = st.tuples(
    NAMES, st.lists(FLOATS, max_size=6), st.lists(FLOATS, max_size=6), st.lists(FLOATS, max_size=6), INT32, UINT32
)
CONTROLLER_EVENT = st.one_of(RAW, JOINT_STATE)


@FUZZ_SETTINGS
@given(events=st.lists(CONTROLLER_EVENT, min_size=1, max_size=6))
def test_controller_survives_fuzzed_joint_states(controller: ControllerHarness, events: list[Any]) -> None:
    peer = controller.peer
    for event in events:
        if isinstance(event, bytes):
            controller.state_pub.publish(event)
            continue
        names, position, velocity, effort, sec, nanosec = event
        msg = JointState(name=list(names), position=position, velocity=velocity, effort=effort)
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
        controller.state_pub.publish(msg)
    # A valid state: answered, with finite numbers.
    stamp_ns = controller.next_stamp_ms * 10**6
    controller.next_stamp_ms += 1
    valid = JointState(name=JOINTS, position=START, velocity=[0.0] * 4, effort=[0.0] * 4)  # the simulator's layout
    valid.header.stamp.sec, valid.header.stamp.nanosec = sec_nanosec(stamp_ns)
    controller.state_pub.publish(valid)
    assert peer.spin_until(lambda: controller.answered(stamp_ns), 10.0), "no answer to a valid state"
    assert controller.process.poll() is None, "the controller died"
    assert not peer.non_finite, peer.non_finite[:3]
