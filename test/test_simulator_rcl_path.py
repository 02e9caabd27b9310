"""The simulator's motor_command path on rcl (bracing_sim.rcl_path, C++) against its Python path: the same bag,
message for message and byte for byte (controller_state but its compute_time, a wall-clock measurement), with
every command the controller sends read in C++.

The simulator's hostile-input tests (test_fuzz, test_hostile_input, test_robustness) run on both paths
(``SIMULATOR_PATHS``)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from ros_helpers import SIMULATOR_PATH_LINES, hold_test_domain
from test_controller_rcl_path import RUN_S, pair_runs, same_bags

from bracing_msgs.msg import MotorCommand
from bracing_rcl import CommandPath, CommandStatus, Layout
from bracing_ros import wire
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


def command(names: list[str], values: list[float], mode: int = MotorCommand.VOLTAGE) -> MotorCommand:
    msg = MotorCommand(mode=mode, name=names, value=values)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 250_000_000
    return msg


def test_the_command_path_reads_only_what_needs_no_word(monkeypatch: pytest.MonkeyPatch) -> None:
    """CommandPath on a real rcl subscription in this process: a command with the template's layout, finite and
    within the limits is read (its stamp and values exactly); every other one comes back as its bytes (the
    message sent) for the Python path: the joints shuffled, a NaN, a value over its joint's limit, another mode,
    too few joints."""
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
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
    context = Context()
    rclpy.init(context=context, domain_id=hold_test_domain())
    try:
        node = rclpy.create_node("command_path_test", context=context)
        qos = QoSProfile(depth=100)
        subscription = node.create_subscription(MotorCommand, "motor_command", lambda _: None, qos, raw=True)
        publisher = node.create_publisher(MotorCommand, "motor_command", qos)
        path = CommandPath(subscription.handle.pointer, Layout(*template.layout()), limit)
        waiter = SubscriptionWaiter(node, subscription)
        taken = []
        for msg in [good, *handed_over]:
            publisher.publish(msg)
            assert waiter.wait(10.0), "the command did not come"
            taken.append(path.take())
            assert path.take().status == CommandStatus.empty
    finally:
        rclpy.try_shutdown(context=context)
    assert taken[0].status == CommandStatus.taken and taken[0].data is None
    assert taken[0].stamp_ns == 3_250_000_000 and taken[0].values == [1.5, -300.0, 5.0, -0.25]
    for take, msg in zip(taken[1:], handed_over, strict=True):
        assert take.status == CommandStatus.python and take.values == []
        assert take.data is not None and repr(deserialize_message(take.data, MotorCommand)) == repr(msg)  # NaN too
