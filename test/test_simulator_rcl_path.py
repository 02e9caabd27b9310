"""The simulator's motor_command path on rcl (bracing_sim.rcl_path, C++) against its Python path: the same bag,
message for message and byte for byte (controller_state but its compute_time, a wall-clock measurement), with
every command the controller sends read in C++, and the state and the step's reports written in C++: as the
recorder has them from the record batches (bracing-pair's default) and as it has them from each topic
(record_batch 0: the bytes published).

The simulator's hostile-input tests (test_fuzz, test_hostile_input, test_robustness) run on both paths
(``SIMULATOR_PATHS``)."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import WrenchStamped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.context import Context
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from ros_helpers import SIMULATOR_PATH_LINES, hold_test_domain
from test_controller_rcl_path import RUN_S, pair_runs, same_bags

from bracing_core.dynamics import InputMode
from bracing_engine import check_command, command_api
from bracing_msgs.msg import Contacts, MotorCommand, MotorState
from bracing_rcl import CommandPath, CommandStatus, CommandTake, Layout, ReportPath
from bracing_ros import report_encoders, wire
from bracing_ros.commands import CommandError, command_vector
from bracing_ros.report_encoders import ContactReport
from bracing_ros.waiter import SubscriptionWaiter
from bracing_sim.rcl_path import PATH_ENV, STATE_PATH_LINE


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A pair run of the paper's arm with the simulator on each path."""
    return pair_runs(tmp_path_factory, PATH_ENV, SIMULATOR_PATH_LINES)


def test_each_run_took_its_path(runs: dict[str, Path]) -> None:
    """The Python path said so; the C++ path wrote joint_states and /clock and read the commands itself (the
    controller's have the template's layout) and handed none over. A command may come while the node's
    executor serves its services (every 100 steps): the executor's callback takes it on the Python path, as
    before."""
    for path, output in runs.items():
        log = (output / "logs" / "simulator.log").read_text()
        assert SIMULATOR_PATH_LINES[path] in log, log[-3000:]
    log = (runs["rcl"] / "logs" / "simulator.log").read_text()
    assert STATE_PATH_LINE in log, log[-3000:]
    assert STATE_PATH_LINE not in (runs["python"] / "logs" / "simulator.log").read_text()
    found = re.search(r"motor_command path: (\d+) read in C\+\+ on rcl, (\d+) by the Python path", log)
    assert found is not None, log[-3000:]
    commands = round(RUN_S * 1000) + 1  # one per state, the final one's too
    assert commands - 4 <= int(found[1]) <= commands and int(found[2]) == 0, found[0]


def test_the_rcl_path_bag_equals_the_python_path_bag(runs: dict[str, Path]) -> None:
    assert len(same_bags(runs)["/joint_states"]) == round(RUN_S * 1000) + 1


@pytest.fixture(scope="module")
def unbatched_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """As ``runs``, the recorder subscribed to each topic (no record batch): it records the bytes published."""
    return pair_runs(tmp_path_factory, PATH_ENV, SIMULATOR_PATH_LINES, "--set", "record_batch=0")


def test_the_bytes_published_are_the_python_path_s(unbatched_runs: dict[str, Path]) -> None:
    """Every state's joint_states and /clock and every step's reports, as published on each path."""
    log = (unbatched_runs["rcl"] / "logs" / "simulator.log").read_text()
    assert STATE_PATH_LINE in log, log[-3000:]
    bag = same_bags(unbatched_runs)
    states = round(RUN_S * 1000) + 1
    for topic in ("/joint_states", "/clock", "/contacts", "/motor_state", "/contact_wrench/elbow"):
        assert len(bag[topic]) == states, topic


def command(names: list[str], values: list[float], mode: int = MotorCommand.VOLTAGE) -> MotorCommand:
    msg = MotorCommand(mode=mode, name=names, value=values)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 250_000_000
    return msg


CommandTopic = tuple[Publisher, Subscription, SubscriptionWaiter, Node]


@pytest.fixture
def command_topic(monkeypatch: pytest.MonkeyPatch) -> Iterator[CommandTopic]:
    """motor_command in a domain of its own: a publisher, a raw subscription and its waiter, their node, in this
    process."""
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = Context()
    rclpy.init(context=context, domain_id=hold_test_domain())
    try:
        node = rclpy.create_node("command_rule_test", context=context)
        qos = QoSProfile(depth=100)
        subscription = node.create_subscription(MotorCommand, "motor_command", lambda _: None, qos, raw=True)
        yield (
            node.create_publisher(MotorCommand, "motor_command", qos),
            subscription,
            SubscriptionWaiter(node, subscription),
            node,
        )
    finally:
        rclpy.try_shutdown(context=context)


def command_path(node: Node, subscription: Subscription, layout: Layout, limit: list[float]) -> CommandPath:
    """A CommandPath on ``subscription`` (its wait's guard condition one of ``node``'s)."""
    interrupt = node.create_guard_condition(lambda: None)
    context: Any = node.context.handle  # rclpy's stubs know no pointer (its rcl_context_t*)
    return CommandPath(
        command_api(), subscription.handle.pointer, context.pointer, interrupt.handle.pointer, layout, limit
    )


def test_the_command_path_reads_only_what_needs_no_word(command_topic: CommandTopic) -> None:
    """CommandPath on a real rcl subscription in this process: a command with the template's layout, finite and
    within the limits is read (its stamp and values exactly); every other one comes back as its bytes (the
    message sent) for the Python path: the joints shuffled, a NaN, a value over its joint's limit, another mode,
    too few joints."""
    publisher, subscription, _, node = command_topic
    names, limit = ["joint1", "joint2", "joint3", "joint4"], [5.0, 0.0, 5.0, 5.0]  # joint2: no limit
    template = wire.MotorCommandDecoder(names, MotorCommand.VOLTAGE).template
    good = command(names, [1.5, -300.0, 5.0, -0.25])
    handed_over = [
        command([names[k] for k in (3, 0, 2, 1)], [-0.25, 1.5, 5.0, -300.0]),
        command(names, [1.5, math.nan, 0.0, 0.0]),
        command(names, [1.5, 0.0, 5.000001, 0.0]),
        command(names, [1.5, 0.0, 0.0, 0.0], MotorCommand.TORQUE),
        command(names[:3], [1.5, 0.0, 0.0]),
    ]
    path = command_path(node, subscription, Layout(*template.layout()), limit)
    taken = []
    for msg in [good, *handed_over]:
        publisher.publish(msg)
        assert path.wait(10_000_000_000), "the command did not come"  # its wait on rcl, in C++
        taken.append(path.take())
        assert path.take().status == CommandStatus.empty
    assert not path.wait(1_000_000)  # nothing more came
    assert taken[0].status == CommandStatus.taken and taken[0].data is None
    assert taken[0].stamp_ns == 3_250_000_000 and taken[0].values == [1.5, -300.0, 5.0, -0.25]
    for take, msg in zip(taken[1:], handed_over, strict=True):
        assert take.status == CommandStatus.python and take.values == []
        assert take.data is not None and repr(deserialize_message(take.data, MotorCommand)) == repr(msg)  # NaN too


def test_the_report_path_writes_what_the_encoders_write(monkeypatch: pytest.MonkeyPatch) -> None:
    """ReportPath on real rcl publishers in this process, two configured contacts of three, the thermal model's
    temperatures: each report received is the Python path's encoder's bytes (a contact released, a NaN, -0.0
    among the numbers), and the bytes kept for the record batch are the bytes published."""
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rng = np.random.default_rng(7)
    names, frames, joints = ["elbow", "wrist", "hand"], ["link2", "link3", "link4"], ["j1", "j2", "j3"]
    wrench_wire = report_encoders.WrenchStampedEncoder("world")
    contacts_wire = report_encoders.ContactsEncoder(names, frames)
    motor_wire = report_encoders.MotorStateEncoder(joints)
    held = np.array([True, False, True])
    points = [rng.normal(size=(3, 3)) for _ in range(3)]  # positions, normals, slip velocities
    normal_force, friction_force, residual = rng.normal(size=3), rng.normal(size=3), np.array([1e-4, math.nan, -0.0])
    forces = [rng.normal(size=3), np.array([-0.0, 2.5, math.inf])]
    motors = [rng.normal(size=3) for _ in range(4)]  # voltage, current, power, temperature
    energies = (1.5, -0.25, 0.125)
    stamp_ns = 12_345_678_901
    forces_at = [(normal_force[j], friction_force[j]) for j in range(3)]
    reports = [
        ContactReport(bool(held[j]), points[0][j], points[1][j], *forces_at[j], points[2][j], residual[j])
        for j in range(3)
    ]
    expected = {
        "contact_wrench/elbow": wrench_wire.encode(stamp_ns, forces[0]),
        "contact_wrench/wrist": wrench_wire.encode(stamp_ns, forces[1]),
        "contacts": contacts_wire.encode(stamp_ns, reports),
        "motor_state": motor_wire.encode(stamp_ns, *motors[:3], energies, motors[3]),
    }
    context = Context()
    rclpy.init(context=context, domain_id=hold_test_domain())
    try:
        node = rclpy.create_node("report_path_test", context=context)
        qos = QoSProfile(depth=10)
        types = {"contact_wrench/elbow": WrenchStamped, "contact_wrench/wrist": WrenchStamped}
        types |= {"contacts": Contacts, "motor_state": MotorState}
        pubs = {topic: node.create_publisher(kind, topic, qos) for topic, kind in types.items()}
        subs = {
            topic: node.create_subscription(kind, topic, lambda _: None, qos, raw=True) for topic, kind in types.items()
        }
        deadline = time.monotonic() + 10.0
        while not all(pub.get_subscription_count() for pub in pubs.values()) and time.monotonic() < deadline:
            time.sleep(0.01)
        templates = (wrench_wire.template(), contacts_wire.template(), motor_wire.template(3))
        layouts = [Layout(*template.layout()) for template in templates]
        handles = {topic: pub.handle.pointer for topic, pub in pubs.items()}
        wrench_pubs = [handles["contact_wrench/elbow"], handles["contact_wrench/wrist"]]
        path = ReportPath(wrench_pubs, handles["contacts"], handles["motor_state"], *layouts, True)
        sent = path.publish(stamp_ns, forces, held, points[0], points[1], normal_force, friction_force, points[2],
                            residual, *motors, energies)  # fmt: skip
        with pytest.raises(ValueError, match="contacts do not fit"):
            path.publish(stamp_ns, forces, held[:2], points[0][:2], points[1][:2], normal_force[:2],
                         friction_force[:2], points[2][:2], residual[:2], *motors, energies)  # fmt: skip
        received = {}
        for topic, sub in subs.items():
            waiter = SubscriptionWaiter(node, sub)
            taken = waiter.take(10.0)
            assert len(taken) == 1, topic
            received[topic] = bytes(taken[0])
    finally:
        rclpy.try_shutdown(context=context)
    assert received == expected
    assert sent.wrenches == [expected["contact_wrench/elbow"], expected["contact_wrench/wrist"]]
    assert (sent.contacts, sent.motor_state) == (expected["contacts"], expected["motor_state"])
    assert sent.written_s > 0.0


# The value rule's cases: any float (NaN, +-inf, subnormals, huge), and values at and around a joint's limit.
JOINTS = ["joint1", "joint2", "joint3", "joint4"]
LIMITS = st.sampled_from([0.0, 5.0, 0.5, 1e-300, 5e-324, 1e300, math.inf, -1.0, math.nan])  # <= 0, NaN: none


@st.composite
def limited_values(draw: st.DrawFn) -> tuple[list[float], list[float]]:
    """(values, limit) per joint: each value any float or one next to its joint's limit (or to zero)."""
    limit = draw(st.lists(LIMITS, min_size=len(JOINTS), max_size=len(JOINTS)))
    values = []
    for b in limit:
        near = [0.0, -0.0, b, -b, math.nextafter(b, math.inf), math.nextafter(b, 0.0), math.nextafter(-b, -math.inf)]
        values.append(draw(st.one_of(st.floats(), st.sampled_from(near))))
    return values, limit


def clipped_as_numpy_did(values: list[float], limit: list[float]) -> tuple[np.ndarray, bool] | None:
    """The rule as the Python path wrote it in NumPy before the engine took it over (the oracle): None for a
    non-finite value, else the command and whether it was saturated."""
    u = np.array(values, dtype=float)
    if not np.isfinite(u).all():
        return None
    bound = np.where(np.asarray(limit) > 0.0, limit, np.inf)
    saturated = bool(np.any(np.abs(u) > bound))
    return (np.clip(u, -bound, bound) if saturated else u), saturated


def test_both_command_paths_apply_one_value_rule(command_topic: CommandTopic) -> None:
    """Over generated values and limits (any float, at and around each limit, zero, negative and NaN limits): the
    C++ path (CommandPath on rcl) reads a command exactly when the Python path (command_vector) takes it without a
    word, with the same values bit for bit; the Python path refuses a non-finite value naming its joints and
    saturates as np.clip did, bit for bit (the NumPy rule both replaced)."""
    publisher, subscription, waiter, node = command_topic
    layout = Layout(*wire.MotorCommandDecoder(JOINTS, MotorCommand.VOLTAGE).template.layout())

    @settings(max_examples=300, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow])  # fmt: skip
    @given(limited_values())
    def agree(case: tuple[list[float], list[float]]) -> None:
        values, limit = case
        path = command_path(node, subscription, layout, limit)
        publisher.publish(command(JOINTS, values))
        assert waiter.wait(10.0), "the command did not come"
        taken = path.take()
        assert path.take().status == CommandStatus.empty
        expected = clipped_as_numpy_did(values, limit)
        if expected is None:
            assert_refused_non_finite(values, limit, taken)
        else:
            assert_applied(values, limit, taken, *expected)

    agree()


def assert_refused_non_finite(values: list[float], limit: list[float], taken: CommandTake) -> None:
    """Both paths refuse a non-finite value: the C++ path hands it over, the Python path says which joints."""
    assert taken.status == CommandStatus.python and taken.values == []
    bad = [j for j, v in zip(JOINTS, values, strict=True) if not math.isfinite(v)]
    with pytest.raises(CommandError) as refused:
        command_vector(JOINTS, values, MotorCommand.VOLTAGE, JOINTS, InputMode.VOLTAGE, np.array(limit))
    named = str(bad[:3]) + (f" and {len(bad) - 3} more" if len(bad) > 3 else "")  # quote_names: 3 at most
    assert refused.value.kind == "non-finite" and str(refused.value) == f"non-finite values for {named}"
    assert check_command(np.array(values), np.array(limit)).non_finite == [JOINTS.index(j) for j in bad]


def assert_applied(values: list[float], limit: list[float], taken: CommandTake, u: np.ndarray, saturated: bool) -> None:
    """Finite: the Python path's command is np.clip's bit for bit, and the C++ path read it iff none saturated."""
    got, got_saturated = command_vector(
        JOINTS, values, MotorCommand.VOLTAGE, JOINTS, InputMode.VOLTAGE, np.array(limit)
    )
    assert got_saturated == saturated and got.tobytes() == u.tobytes(), (values, limit, got, u)
    if saturated:
        assert taken.status == CommandStatus.python and taken.values == []
    else:
        assert taken.status == CommandStatus.taken and taken.stamp_ns == 3_250_000_000
        assert np.array(taken.values).tobytes() == u.tobytes(), (values, limit, taken.values)
