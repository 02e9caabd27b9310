"""Clocks that jump and robots that go away: /clock negative, back or far ahead on every node that
follows it (use_sim_time), effort_forward's state_timeout, and the controller's stop after its
simulator was killed.

The policies are ROS-free (``bracing_core.sim_clock``, ``bracing_core.state_freshness``) and tested
first without DDS; then each node runs as its own process and this test process is a real rclpy
participant in its domain that sends it the hostile /clock messages (bounded in count and time).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import rclpy
from builtin_interfaces.msg import Time
from lockstep_driver import JOINTS
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import isolated_env, node_argv, pair_argv, params_file, start
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from test_fuzz import Peer, start_peer
from test_pair import _wait_for_progress, read_bag
from test_stepping import Log

from bracing_bringup.domains import hold_domain
from bracing_core.sim_clock import ClockGuard
from bracing_core.state_freshness import StateFreshness
from bracing_msgs.msg import RunStatus
from bracing_ros.ack_window import AckWindow
from bracing_ros.qos import STATUS_QOS

S = 1_000_000_000  # ns per s


# -- the policies: no DDS ----------------------------------------------------------------------------
def test_clock_guard_refuses_negative_and_malformed_and_takes_jumps_as_ros_does() -> None:
    log = Log()
    guard = ClockGuard(log)
    assert guard.take(5, 0) == 5 * S  # the first one: no jump to speak of (from 0 to wherever the run is)
    assert guard.take(-1, 0) is None and guard.last_ns == 5 * S  # refused: the clock stays
    assert guard.take(-(2**31), 999) is None
    assert guard.take(6, 1_000_000_000) is None  # nanosec outside builtin_interfaces/Time's [0, 10^9)
    assert guard.take(5, 10_000_000) == 5 * S + 10_000_000  # 10 ms on: nothing to report
    assert guard.take(1, 0) == 1 * S  # back: a reset, taken
    assert guard.take(1, 500_000_000) == 1 * S + 500_000_000  # 0.5 s on: taken silently
    far = guard.take(2**31 - 1, 999_999_999)  # ~68 years on: taken (int64 ns holds it)
    assert far == (2**31 - 1) * S + 999_999_999
    assert log.kinds() == ["clock-negative", "clock-negative", "clock-malformed", "clock-back", "clock-ahead"]
    assert all(level == "warning" for level, _, _ in log.reports)
    negative = log.reports[0][2]
    assert negative == "/clock refused: negative time (sec -1); clock 5.000000000 s"
    assert log.reports[3][2].startswith("/clock jumped back from 5.010000000 s to 1.000000000 s: taken as a reset")
    assert "jumped 2147483646.499999999 s ahead, from 1.500000000 s" in log.reports[4][2]


def test_state_freshness_off_answers_every_state_and_never_sends_zeros() -> None:
    log = Log()
    fresh = StateFreshness(0.0, log)
    fresh.received(0)
    fresh.answered()
    assert fresh.usable(10**18) and fresh.usable(-1) and not fresh.zero_due(10**18)
    assert log.reports == []


def test_state_freshness_answers_within_state_timeout_then_zeros_until_a_state_is_answered() -> None:
    log = Log()
    fresh = StateFreshness(0.05, log)
    assert fresh.usable(0) and not fresh.zero_due(0)  # nothing yet: nothing to answer, no zeros either
    fresh.received(1 * S)
    assert fresh.usable(1 * S)
    fresh.answered()
    assert not fresh.zero_due(1 * S + 50_000_000)  # exactly state_timeout old: still answered
    assert fresh.usable(1 * S + 50_000_000)
    late = 1 * S + 50_000_001
    assert not fresh.usable(late) and fresh.zero_due(late)  # 1 ns past it: zeros, not a command
    assert fresh.zero_due(late + S)  # and on, told once
    assert log.kinds() == ["state-stale"]
    assert "no state answered for 0.050000001 s; state_timeout 0.05 s" in log.reports[0][2]
    fresh.received(3 * S)  # states again: answered, the law's efforts resume (said once)
    assert fresh.usable(3 * S)
    fresh.answered()
    assert not fresh.zero_due(3 * S)
    assert log.kinds() == ["state-stale", "state-resumed"]
    # a state that comes but is refused (not answered) does not keep the efforts going
    fresh.received(3 * S + 40_000_000)
    assert fresh.usable(3 * S + 60_000_000) and fresh.zero_due(3 * S + 60_000_000)


def test_state_freshness_takes_a_jump_back_as_a_reset() -> None:
    """A state that arrived at 5 s is not answered once the clock says 1 s (it came after the new time)."""
    log = Log()
    fresh = StateFreshness(0.05, log)
    fresh.received(5 * S)
    fresh.answered()
    assert not fresh.usable(1 * S) and fresh.zero_due(1 * S)
    assert "the clock jumped back past the last state answered" in log.reports[0][2]
    fresh.received(1 * S + 10_000_000)
    assert fresh.usable(1 * S + 10_000_000)


# -- over DDS: every node that follows /clock ---------------------------------------------------------
HOSTILE = [(-1, 0), (-(2**31), 0), (3, 4_000_000_000), (7, 0), (0, 0), (2**31 - 1, 999_999_999)]
"""(sec, nanosec): negative twice, nanosec out of range, 7 s, back to 0 (a reset), ~68 years ahead."""
RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


def _close(peer: Peer, *processes: subprocess.Popen[str]) -> list[str]:
    """Stop the peer, then each process still running (SIGTERM); their logs."""
    peer.executor.shutdown()
    peer.node.destroy_node()
    rclpy.try_shutdown(context=peer.context)
    for process in processes:
        if process.poll() is None:
            process.terminate()
    return [process.communicate(timeout=30)[0] for process in processes]


def _send_hostile_clocks(peer: Peer, subscribers: int) -> None:
    """Each HOSTILE /clock in turn, repeated for 1 s (25 times): rclpy's /clock subscription keeps the
    latest one only (depth 1), so each is the latest for long enough to be taken. Sent while the run
    waits for this peer on run_status (min_status_subscribers 1): the nodes serve their executors then,
    and the run's own /clock is not yet there to overwrite them."""
    hostile = peer.node.create_publisher(Clock, "/clock", RELIABLE)
    assert peer.spin_until(lambda: hostile.get_subscription_count() >= subscribers, 60)
    for sec, nanosec in HOSTILE:
        for _ in range(25):
            hostile.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
            peer.spin_until(lambda: False, 0.04)


def _release(peer: Peer) -> None:
    """Subscribe run_status: the run (min_status_subscribers 1) starts stepping."""
    peer.node.create_subscription(RunStatus, "run_status", lambda _: None, STATUS_QOS)


def _commands(peer: Peer) -> list[list[float]]:
    """effort_controller/commands as they come (a forward controller's reader, volatile)."""
    commands: list[list[float]] = []
    peer.node.create_subscription(
        Float64MultiArray, "effort_controller/commands", lambda m: commands.append(list(m.data)), RELIABLE
    )
    return commands


def _refusals_in(log: str) -> None:
    assert "/clock refused: negative time (sec -1)" in log, log[-3000:]
    assert "/clock refused: nanosec 4000000000 outside [0, 10^9)" in log, log[-3000:]
    assert "/clock jumped back from" in log and "Traceback" not in log, log[-3000:]


WAITING = {"min_status_subscribers": 1, "use_sim_time": True}


def test_lockstep_pair_under_use_sim_time_survives_hostile_clocks(tmp_path: Path) -> None:
    """The simulator and the lockstep controller, both with use_sim_time (each follows the simulator's
    /clock): every hostile /clock is refused or taken as a jump, and the run then goes as it would have:
    every step taken in lockstep (the controller answered each state in time)."""
    env = isolated_env()
    sim_params = {"duration": 1.0, **WAITING}
    sim = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim_params)), env)
    ctl_params = {"use_sim_time": True}
    ctl = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl_params)), env)
    peer = start_peer(env, "hostile_clock")
    try:
        _send_hostile_clocks(peer, subscribers=2)
        _release(peer)
        peer.spin_until(lambda: sim.poll() is not None, 120)
        controller_alive = ctl.poll() is None
    finally:
        sim_log, ctl_log = _close(peer, sim, ctl)
    assert sim.returncode == 0 and "finished at t = 1.000000 s" in sim_log, sim_log[-3000:]
    assert "no valid motor_command" not in sim_log  # every state answered in time
    assert controller_alive and ctl.returncode == 0, ctl_log[-3000:]
    _refusals_in(sim_log)
    _refusals_in(ctl_log)
    assert "/clock jumped 2147483647.999999999 s ahead, from 0.000000000 s" in sim_log  # after the reset to 0


def test_mujoco_robot_and_effort_forward_controller_survive_hostile_clocks(tmp_path: Path) -> None:
    """bracing-pair --engine mujoco's two nodes (the MuJoCo robot publishing /clock, the controller in
    effort_forward following it with use_sim_time): after the hostile /clock both run on, the robot to
    its end, the controller answering (each robot step waits for a command, or 50 ms of wall time)."""
    env = isolated_env()
    robot_params = {"duration": 0.5, "wait_for_recorder": False, **WAITING}
    robot = start(
        node_argv("bracing_mujoco.mujoco_robot", params_file(tmp_path, "bracing_simulator", robot_params)), env
    )
    ctl_params = {"input_mode": "torque", "command_output": "effort_forward", "use_sim_time": True}
    ctl = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl_params)), env)
    peer = start_peer(env, "hostile_clock")
    received = _commands(peer)
    try:
        _send_hostile_clocks(peer, subscribers=2)
        before = len(received)
        _release(peer)
        peer.spin_until(lambda: robot.poll() is not None, 120)
        peer.spin_until(lambda: False, 0.2)
        controller_alive = ctl.poll() is None
    finally:
        robot_log, ctl_log = _close(peer, robot, ctl)
    assert robot.returncode == 0 and "finished at t = 0.500000 s" in robot_log, robot_log[-3000:]
    assert controller_alive and ctl.returncode == 0, ctl_log[-3000:]
    _refusals_in(robot_log)
    _refusals_in(ctl_log)
    commands = received[before:]
    # the law's efforts through the run: about one per step of 1 ms (the timer follows the robot's /clock)
    assert len(commands) >= 400, (len(commands), ctl_log[-3000:])
    assert any(abs(v) > 0.0 for command in commands for v in command)


def test_mujoco_pair_survives_a_negative_clock_mid_run(tmp_path: Path) -> None:
    """The reported run: bracing-pair --engine mujoco, and a peer that sends hostile /clock messages
    mid-run (reliable and transient-local: they reach the recorder's /clock reader as well as the
    controller's). The run ends as one without them: exit 0, the elbow braced throughout; the controller
    refused the negative ones; the recorder kept them (at log time 0) and the bag reads."""
    with hold_domain() as domain:
        env = isolated_env(domain.domain_id)
        output = tmp_path / "run"
        argv = pair_argv(output, "--engine", "mujoco", "--mode", "torque", "--duration", "3", "--no-animation")
        pair = start([*argv, "--domain-id", str(domain.domain_id)], env)
        peer = start_peer(env, "hostile_clock")
        try:
            clocks: list[float] = []
            peer.node.create_subscription(
                Clock, "/clock", lambda m: clocks.append(m.clock.sec + m.clock.nanosec * 1e-9), 10
            )
            latched = QoSProfile(
                depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
            )
            hostile = peer.node.create_publisher(Clock, "/clock", latched)

            def ready() -> bool:
                """Matched with the controller's /clock reader (use_sim_time), the recorder's and this peer's;
                the run 0.3 s in."""
                return hostile.get_subscription_count() >= 3 and bool(clocks) and clocks[-1] >= 0.3

            peer.spin_until(lambda: ready() or pair.poll() is not None, 120)
            assert ready(), "the run ended before this peer had matched it"
            for _ in range(20):
                for sec, nanosec in HOSTILE:
                    hostile.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
                    peer.spin_until(lambda: False, 0.005)
            out = pair.communicate(timeout=180)[0]
        finally:
            _close(peer)
            if pair.poll() is None:
                pair.kill()
    assert pair.returncode == 0, out[-3000:]
    summary = json.loads((output / "summary.json").read_text())
    assert summary["contacts"]["elbow"]["active_fraction"] == 1.0
    controller_log = (output / "logs" / "controller.log").read_text()
    assert "/clock refused: negative time" in controller_log and "Traceback" not in controller_log
    recorded = [m.clock.sec for _, m in read_bag(output / "bag")["/clock"]]
    assert -1 in recorded and len(recorded) >= 3000


TICK = 0.01  # [s] of sim time per /clock: one tick of the controller's timer at control_rate 100 Hz
STATE_TIMEOUT = 0.05
Q0 = [-0.6283185307179586, -1.8849555921538759, 2.5132741228718345, -1.2566370614359172]


def _clock_ticks(
    peer: Peer, received: list[list[float]], ticks: list[tuple[float, bool]]
) -> list[tuple[float, list[float]]]:
    """Play the robot's side one tick at a time: /clock at t, then (if asked) a joint_states stamped t,
    then wait for the command of that tick (at most 2 s of wall time: a bound on a stall only). Each
    command comes with the /clock it was computed at (the last one sent before it arrived)."""
    clock = peer.node.create_publisher(Clock, "/clock", RELIABLE)
    states = peer.node.create_publisher(JointState, "joint_states", RELIABLE)
    assert peer.spin_until(lambda: clock.get_subscription_count() >= 1 and states.get_subscription_count() >= 1, 60)
    seen: list[tuple[float, list[float]]] = []
    for t, with_state in ticks:
        count = len(received)
        ns = round(t * S)
        stamp = Time(sec=ns // S, nanosec=ns % S)
        clock.publish(Clock(clock=stamp))
        if with_state:
            state = JointState(name=JOINTS, position=Q0, velocity=[0.0] * 4)
            state.header.stamp = stamp
            states.publish(state)
        peer.spin_until(lambda: len(received) > count, 2.0)  # noqa: B023 (called here, not later)
        seen += [(t, command) for command in received[count:]]
    return seen


def _zero(command: list[float]) -> bool:
    return all(v == 0.0 for v in command)


def test_effort_forward_sends_zeros_once_its_state_is_older_than_state_timeout(tmp_path: Path) -> None:
    """effort_forward, control_rate 100 Hz, state_timeout 0.05 s, use_sim_time; this peer plays the robot
    (/clock 10 ms a tick, joint_states) and the forward controller. Joint states stop at 5.29 s: the law's
    efforts go on until the last state is 0.05 s old on the node's clock (a tick of slack for the order
    in which /clock and the state arrive), zero efforts after it, every tick; states again: the law's
    efforts again. Then /clock jumps back to 1 s (a reset): the state held arrived on the old timeline,
    so zeros until the next state, and the law's efforts after it; a negative /clock in between is refused."""
    ctl = {
        "input_mode": "torque",
        "command_output": "effort_forward",
        "control_rate": 1.0 / TICK,
        "state_timeout": STATE_TIMEOUT,
        "use_sim_time": True,
    }
    env = isolated_env()
    process = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    peer = start_peer(env, "robot_side")
    received = _commands(peer)
    # a writer of its own for the negative tick, matched before it is sent (a late match loses it)
    negative = peer.node.create_publisher(Clock, "/clock", RELIABLE)
    run = [(5.0 + k * TICK, k < 30) for k in range(60)]  # states for 0.3 s, then none for 0.3 s
    run += [(5.6 + k * TICK, True) for k in range(20)]  # states again
    reset = [(1.0 + k * TICK, k >= 10) for k in range(30)]  # back to 1 s; states from 1.1 s
    try:
        seen = _clock_ticks(peer, received, run)
        assert peer.spin_until(lambda: negative.get_subscription_count() >= 1, 60)
        negative.publish(Clock(clock=Time(sec=-1, nanosec=0)))
        seen_reset = _clock_ticks(peer, received, reset)
        alive = process.poll() is None
    finally:
        (log,) = _close(peer, process)
    assert alive and process.returncode == 0, log[-3000:]
    last_state = 5.0 + 29 * TICK
    law = [c for t, c in seen if t <= last_state]
    assert len(law) >= 25 and not any(_zero(c) for c in law), log[-3000:]  # the law's efforts while states come
    # no command from the last state once it is older than state_timeout (+ a tick): zeros, every tick
    after = [c for t, c in seen if last_state + STATE_TIMEOUT + 2 * TICK <= t < 5.6 - 1e-9]
    assert len(after) >= 20 and all(_zero(c) for c in after), seen
    resumed = [c for t, c in seen if t >= 5.6 + 2 * TICK]
    assert len(resumed) >= 15 and not any(_zero(c) for c in resumed), seen
    assert "joint_states stale (no state answered for" in log and "state_timeout 0.05 s)" in log
    assert "joint_states answered again" in log
    # the jump back: the state held (from 5.79 s) is not answered on the new timeline
    before_state = [c for t, c in seen_reset if t < 1.1 - 1e-9]
    assert before_state and all(_zero(c) for c in before_state), seen_reset
    after_state = [c for t, c in seen_reset if t >= 1.1 + 2 * TICK]
    assert len(after_state) >= 15 and not any(_zero(c) for c in after_state), seen_reset
    assert "/clock refused: negative time (sec -1)" in log


# -- a killed simulator: the controller's stop ---------------------------------------------------------
def test_controller_stop_after_a_killed_simulator_says_what_happened(tmp_path: Path) -> None:
    """bracing-pair (lockstep, the recorder on record_batch): SIGKILL on the simulator mid-run. The run
    fails naming it; the controller, stopped, flushes the recorder's copy of its answers only (the
    recorder acknowledges them) and says that the simulator's were not waited for, instead of waiting
    10 s for a reader that DDS keeps matched until its lease ends and calling the answers lost."""
    output = tmp_path / "run"
    pair = start(pair_argv(output, "--duration", "30", "--no-animation"), isolated_env())
    try:
        _wait_for_progress(output)
        found = subprocess.run(["pgrep", "-f", f"bracing_sim.node.*{output}"], capture_output=True, text=True)
        (pid,) = [int(p) for p in found.stdout.split()]
        os.kill(pid, signal.SIGKILL)
        out = pair.communicate(timeout=120)[0]
    finally:
        if pair.poll() is None:
            pair.kill()
    assert pair.returncode == 1 and "simulator exited" in out, out[-3000:]
    log = (output / "logs" / "controller.log").read_text()
    assert "lost to it" not in log and "lost to whichever" not in log, log[-3000:]
    assert "stopping: /motor_command: the last answers are not acknowledged by bracing_simulator" in log, log[-3000:]
    assert "not waited for: the recorder has them in record_batch" in log
    read_bag(output / "bag")  # still readable


SUBSCRIBER = """
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("doomed_subscriber")
reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
node.create_subscription(String, "answers", lambda m: None, reliable)
rclpy.spin(node)
"""


def subscriber_names(node: Node, topic: str) -> list[str]:
    return [info.node_name for info in node.get_subscriptions_info_by_topic(topic)]


def test_ack_window_close_names_what_a_killed_subscriber_did_not_acknowledge() -> None:
    """Without record_batch the stop waits for every subscriber of the answers: one killed (SIGKILL) stays
    matched until its DDS lease ends (~20 s), so the wait ends at its timeout, and the line says which
    messages are not known to have arrived (after the last every subscriber acknowledged) and who was
    matched, not that they were lost to a subscriber that lives."""
    env = isolated_env()
    peer = start_peer(env, "answering")
    child = subprocess.Popen([sys.executable, "-c", SUBSCRIBER], env=env)
    try:
        publisher = peer.node.create_publisher(String, "answers", RELIABLE)
        flow = AckWindow(peer.node, [publisher], 100)
        # Matched is not named: the subscriber's node name comes over ROS's own discovery topic, which can
        # arrive after the endpoint matched (rmw then says _NODE_NAME_UNKNOWN_): wait for the name too.
        assert peer.spin_until(lambda: "doomed_subscriber" in subscriber_names(peer.node, "/answers"), 60)
        for k in range(5):
            publisher.publish(String(data=str(k)))
            flow.sent()
        assert flow.wait(30.0) and flow.acked_count == 5
        child.kill()
        child.wait(10)
        for k in range(5, 8):
            publisher.publish(String(data=str(k)))
            flow.sent()
        lines = flow.close(1.0)
    finally:
        if child.poll() is None:
            child.kill()
        _close(peer)
    assert lines == [
        (
            "error",
            "/answers: not every subscriber (doomed_subscriber) acknowledged the messages after the 5th of 8 "
            "within 1 s: lost to whichever has not (a subscriber killed stays matched until its DDS lease ends, ~20 s)",
        )
    ]
