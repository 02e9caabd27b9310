"""A gain changed while the controller runs leaves a trace in the bag (rclpy's
/parameter_events, the controller's event stamped with the run's sim time) and a vertical line on
the report's figures.

One real bracing-pair run (3 s of sim time, lockstep, over DDS): this test joins its domain,
watches /clock and sets hand.kp through the controller's parameter services half a second in.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import reference_series
from conftest import build_scenario, run_closed_loop
from ros_helpers import hold_test_domain, isolated_env, pair_argv, start
from rosbags.highlevel import AnyReader
from test_recorder_report import N_STEPS, write_bag_directly

from bracing_analysis.bag import read_series
from bracing_analysis.drawing import file_names
from bracing_analysis.figures import plot_figure
from bracing_analysis.series import ParameterChange

DURATION = 4.0
SET_AFTER_S = 0.5  # [s] of sim time
NEW_KP = [150.0, 150.0]


def setter_main(domain: int) -> None:
    """Run in a process of its own (the nodes' Fast DDS profile: discovered as fast as they are): once
    the run's /clock passes SET_AFTER_S, set hand.kp on the controller, as ``ros2 param set`` does."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    from bracing_ros.fastdds import use_fastdds_profile

    use_fastdds_profile()
    rclpy.init(domain_id=domain)
    node = rclpy.create_node("gain_setter")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    now = [0.0]
    # Best effort: the simulator's flow control does not wait for this reader's acknowledgements.
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_subscription(Clock, "/clock", lambda m: now.__setitem__(0, m.clock.sec + m.clock.nanosec * 1e-9), qos)
    client = AsyncParameterClient(node, "bracing_controller")
    deadline = time.monotonic() + 120.0
    while (now[0] < SET_AFTER_S or not client.services_are_ready()) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
    future = client.set_parameters([Parameter("hand.kp", value=NEW_KP)])
    executor.spin_until_future_complete(future, timeout_sec=30.0)
    result = future.result()
    print(f"set at t = {now[0]:.3f} s: {result.results[0].successful if result else None}", flush=True)
    rclpy.shutdown()


def _events(bag: Path) -> list[tuple[int, Any]]:
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/parameter_events"]
        return [
            (stamp, reader.deserialize(raw, c.msgtype)) for c, stamp, raw in reader.messages(connections=connections)
        ]


@pytest.fixture(scope="module")
def tuned_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tuned") / "run"
    domain = hold_test_domain()  # the pair runs in it (--domain-id), and so does this test's node
    argv = pair_argv(out, "--duration", str(DURATION), "--no-animation", "--domain-id", str(domain))
    env = isolated_env(
        domain, PYTHONPATH=os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])
    )
    pair = start(argv, env)
    setter = start([sys.executable, "-c", f"import test_parameter_changes as t; t.setter_main({domain})"], env)
    try:
        said = setter.communicate(timeout=180)[0]
        output = pair.communicate(timeout=300)[0]
    finally:
        for process in (setter, pair):
            if process.poll() is None:
                process.kill()
                process.communicate()
    assert pair.returncode == 0, output
    when = float(said.split("set at t = ")[1].split(" s")[0])
    assert said.strip().endswith("True") and SET_AFTER_S <= when < DURATION - 0.5, said  # mid-run
    return out


def test_the_change_is_in_the_bag_at_the_sim_time_it_took_effect(tuned_run: Path) -> None:
    (stamp, event), *others = _events(tuned_run / "bag")  # the nodes' start-up declarations are not kept
    assert not others
    assert event.node == "/bracing_controller"
    (changed,) = event.changed_parameters
    assert changed.name == "hand.kp" and list(changed.value.double_array_value) == NEW_KP
    event_ns = event.stamp.sec * 1_000_000_000 + event.stamp.nanosec
    assert stamp == event_ns  # the bag's time axis is the run's sim time, as for every other topic
    assert SET_AFTER_S <= event_ns * 1e-9 < DURATION

    # The stamp is the last state answered with the old gain: the recorded commands are the in-process
    # loop's (old gains) up to it, and differ from the next state on.
    with AnyReader([tuned_run / "bag"]) as reader:
        connections = [c for c in reader.connections if c.topic == "/motor_command"]
        commands = sorted(
            (m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec, np.array(m.value))
            for m in (reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections))
        )
    k = event_ns // 1_000_000  # 1 ms steps
    assert commands[k][0] == event_ns
    reference = run_closed_loop(build_scenario(), event_ns * 1e-9 + 0.002)
    recorded = np.array([value for _, value in commands[: k + 2]])
    np.testing.assert_allclose(recorded[: k + 1], reference.command[: k + 1], rtol=0, atol=1e-6)
    assert np.max(np.abs(recorded[k + 1] - reference.command[k + 1])) > 1e-2


def test_every_report_figure_marks_the_change(tuned_run: Path) -> None:
    series = read_series(tuned_run / "bag")
    (change,) = series.parameter_changes
    assert change.node == "/bracing_controller" and change.values == {"hand.kp": NEW_KP}
    assert SET_AFTER_S <= change.t < DURATION
    for name in file_names(series, animation=False):
        axes = plot_figure(name, series).axes[0]
        vertical = [line for line in axes.lines if list(line.get_xdata()) == [change.t, change.t]]
        assert len(vertical) == 1, name
        assert "parameter set" in axes.get_legend_handles_labels()[1], name
        assert [t.get_text() for t in axes.texts] == ["hand.kp = [150.0, 150.0]"], name


def test_a_bag_without_changes_draws_no_lines(tmp_path: Path) -> None:
    write_bag_directly(tmp_path / "bag", N_STEPS, ("elbow",))
    for read in (read_series, reference_series.read_series):
        series = read(tmp_path / "bag")
        assert series.parameter_changes == []
        axes = plot_figure("hand_y", series).axes[0]
        assert not axes.texts and "parameter set" not in axes.get_legend_handles_labels()[1]
    assert ParameterChange(1.5, "/c", {"a": 1, "b": [2.0]}).text() == "a = 1, b = [2.0]"
