"""ros2_control's topic conventions both ways, and targets while running.

No rclcpp wheel exists, so the controller_manager cannot run here: the ros2_control side is played by
rclpy peers (test/ros2_control_peer.py) that behave as its components are documented to (QoS, joint
order, lengths, refusal of wrong sizes and non-finite values), over DDS between processes.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import build_scenario, node_params
from ros_helpers import REPO_ROOT, isolated_env, node_argv, params_file, start

from bracing_core.drive import CurrentLoopDrive, DriveGains
from bracing_core.params import ConfigError
from bracing_core.targets import Goal, Reference, TargetError, check_point
from bracing_ros.commands import CommandError, effort_vector

PEER = str(REPO_ROOT / "test" / "ros2_control_peer.py")
JOINTS = ["joint1", "joint2", "joint3", "joint4"]


# -- the drive: no DDS -------------------------------------------------------------------------------
@pytest.mark.parametrize(("sample", "tolerance"), [(1e-5, 1e-3), (1e-3, 0.025)])
def test_current_loop_tracks_a_torque_step_as_a_first_order_lag(sample: float, tolerance: float) -> None:
    """Hand check: the paper's motor (L 0.17 H, R 0.6 ohm, K_m = K k = 0.2 * 100 N m/A) turning at a
    constant 0.3 rad/s; kp = L w, ki = R w cancel the winding's pole, so with the back-EMF fed forward
    the current answers a torque step as i*(1 - exp(-w t)), w = 100 rad/s: 63.2 % at 10 ms, 86.5 % at
    20 ms, 99.3 % at 50 ms. The circuit L di/dt = v - R i - K_m dq is integrated exactly over each held
    voltage. Sampled at 10 us the loop is the continuous one (0.1 % of the step); at the simulator's
    1 ms step the discrete PI leads by up to 2 % (w * step = 0.1)."""
    inductance, resistance, constant, bandwidth = 0.17, 0.6, 20.0, 100.0
    drive = CurrentLoopDrive(
        DriveGains.from_bandwidth(bandwidth, np.array([inductance]), np.array([resistance])), np.array([constant])
    )
    assert drive.kp[0] == pytest.approx(17.0) and drive.ki[0] == pytest.approx(60.0)
    torque, velocity, current = np.array([5.0]), np.array([0.3]), np.zeros(1)
    wanted = torque[0] / constant  # i* [A]
    decay = math.exp(-resistance * sample / inductance)
    checks = {round(t / sample): t for t in (0.01, 0.02, 0.05)}
    for k in range(1, max(checks) + 1):
        v = drive.voltage(torque, current, velocity, sample)
        drive.commit()
        current = current * decay + (v - constant * velocity) / resistance * (1.0 - decay)
        if k in checks:
            assert current[0] / wanted == pytest.approx(1.0 - math.exp(-bandwidth * checks[k]), abs=tolerance)


def test_current_loop_saturates_at_the_voltage_limit_without_winding_up() -> None:
    drive = CurrentLoopDrive(DriveGains(np.array([17.0]), np.array([60.0])), np.array([20.0]), voltage_limit=12.0)
    for _ in range(1000):
        v = drive.voltage(np.array([1e4]), np.zeros(1), np.zeros(1), 1e-3)
        drive.commit()
        assert abs(v[0]) <= 12.0
    assert drive.integral[0] == 0.0  # held while the limit was pushed


def test_joint_command_refusals_name_what_was_wrong() -> None:
    assert effort_vector(["joint2", "joint1"], [2.0, 1.0], ["joint1", "joint2"])[0].tolist() == [1.0, 2.0]
    for names, efforts, kind in (
        (["joint1", "joint2"], [1.0], "length"),
        (["joint1", "joint9"], [1.0, 2.0], "unknown-names"),
        (["joint1"], [1.0], "missing-names"),
        (["joint1", "joint2"], [1.0, math.nan], "non-finite"),
    ):
        with pytest.raises(CommandError) as caught:
            effort_vector(names, efforts, ["joint1", "joint2"])
        assert caught.value.kind == kind


# -- the reference toward a new target: no DDS --------------------------------------------------------
def test_reference_moves_to_a_new_target_without_a_kick() -> None:
    """From a moving reference (0.08 m/s, across), toward a point 0.2 m away: position and
    velocity continuous, |v| <= v_max and |a| <= a_max throughout, then there and at rest."""
    v_max, a_max, dt = 0.1, 0.5, 1e-3
    reference = Reference(np.array([0.0, 1.1, 0.8]), np.array([0.0, -0.08, 0.0]), 2.0, v_max, a_max)
    reference.goal = Goal(np.zeros(1), np.array([[0.0, 1.0, 0.63]]))
    previous = reference.velocity.copy()
    for k in range(1, 6001):
        _, velocity = reference.advance(2.0 + k * dt)
        assert np.linalg.norm(velocity) <= v_max + 1e-12
        assert np.linalg.norm(velocity - previous) <= a_max * dt + 1e-12
        previous = velocity.copy()
    assert reference.position.tolist() == [0.0, 1.0, 0.63]
    assert not reference.velocity.any()


def test_target_checks_refuse_other_frames_non_finite_and_out_of_reach() -> None:
    from bracing_core.checks import frame_reach

    scenario = build_scenario(with_controller=False)
    plant = scenario.plant
    reach = frame_reach(plant.robot.model, plant.frame_id("hand", "hand.frame"))
    assert check_point("hand_target", [0.0, 1.0, 0.7], "world", (1, 2), reach).tolist() == [0.0, 1.0, 0.7]
    for point, frame, words in (
        ([0.0, 5.0, 5.0], "world", "out of reach"),
        ([0.0, 1.0, 0.7], "base_link", "frame 'base_link'"),
        ([0.0, math.inf, 0.7], "world", "not finite"),
    ):
        with pytest.raises(TargetError, match=words):
            check_point("hand_target", point, frame, (1, 2), reach)


def test_effort_forward_needs_torque_input_and_every_joint_once() -> None:
    from bracing_core.controller_config import ControllerConfig

    with pytest.raises(ConfigError, match="input_mode to torque"):
        ControllerConfig.from_params(node_params("bracing_controller", own={"command_output": "effort_forward"}))
    with pytest.raises(ConfigError, match="effort_command_joints"):
        ControllerConfig.from_params(
            node_params(
                "bracing_controller",
                shared={"input_mode": "torque"},
                own={"command_output": "effort_forward", "effort_command_joints": ["joint1", "joint2"]},
            )
        )


# -- over DDS -----------------------------------------------------------------------------------------
def _peer(args: list[str], env: dict[str, str], timeout: float = 180) -> dict:
    done = subprocess.run([sys.executable, PEER, *args], env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stdout + done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _stop(process: subprocess.Popen[str]) -> str:
    if process.poll() is None:
        process.terminate()
    return process.communicate(timeout=30)[0]


def answer_applied(effort: np.ndarray, answers: list[np.ndarray]) -> int:
    """The state whose answer ``effort`` is (the latest such), or -1 for zero before any answer came."""
    same = [j for j, answer in enumerate(answers) if np.allclose(effort, answer, rtol=0, atol=1e-9)]
    if not same and not effort.any():
        return -1
    assert same, (effort, answers[-3:])  # an effort the law never answered: a wrong joint, a mixed command
    return same[-1]


def test_simulator_under_joint_state_efforts_reproduces_the_lockstep_torque_run(tmp_path: Path) -> None:
    """Our torque law behind a JointStateTopicSystem peer (efforts by name, shuffled; only `effort`
    filled): the simulator stepping in real time (50 ms a step, so an answer usually lands before the next
    tick: lockstep order) gives the in-process torque run's states to 1e-9 under the efforts it applied,
    each the law's answer to a state no later than the step's own, in order, and the answers used one
    after another (a busy machine may make an answer miss its tick: the one before is held, as ros2_control
    would; on an idle one every step applies the answer to its own state)."""
    steps = 60
    env = isolated_env()
    sim = {
        "input_mode": "torque",
        "command_source": "joint_commands",
        "stepping": "real_time",
        "real_time_factor": 0.02,
        "duration": (steps - 1) * 0.001,
        # the peer's two subscriptions (reliable, SensorDataQoS): the run starts once both are matched (with
        # one, a busy machine once started it before the reliable one matched, which then missed the first state)
        "min_subscribers": 2,
    }
    process = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        ctl = node_params("bracing_controller", shared={"input_mode": "torque"})
        seen = _peer(["topic-system", str(steps), json.dumps(ctl)], env)
    finally:
        log = _stop(process)
    states = seen["states"]
    assert len(states) == steps, log
    assert seen["best_effort_received"] > 0  # a SensorDataQoS subscriber is served too
    scenario = build_scenario(shared={"input_mode": "torque"})
    sim_core, law = scenario.sim, scenario.controller
    assert law is not None
    answers: list[np.ndarray] = []  # the law's answer to each state, as the peer computed it
    applied_to: list[int] = []  # for each step, the state whose answer it applied
    for k, state in enumerate(states):
        assert state["t"] == pytest.approx(k * 0.001, abs=1e-12)
        np.testing.assert_allclose(state["position"], sim_core.position, rtol=0, atol=1e-9)
        np.testing.assert_allclose(state["velocity"], sim_core.velocity, rtol=0, atol=1e-9)
        answers.append(law.update(k * 0.001, sim_core.position, sim_core.velocity).command)
        if k + 1 < steps:
            effort = np.array(states[k + 1]["effort"])  # the effort applied from state k to k + 1
            applied_to.append(answer_applied(effort, answers))
            sim_core.step(effort)
    assert applied_to == sorted(applied_to), applied_to  # in order, never an older answer after a newer
    assert len(set(applied_to) - {-1}) >= steps // 2, applied_to  # the answers followed one another


def test_controller_sends_a_forward_controllers_float64multiarray(tmp_path: Path) -> None:
    """effort_forward: one value per joint in a shuffled effort_command_joints order (the law's torque
    for the state, joints matched by name), a reliable publisher; a NaN state or one missing a joint
    gets no command (and a warning). States come as joint_state_broadcaster sends them (SystemDefaultsQoS,
    NaN efforts: a joint without an effort state interface) and from a SensorDataQoS publisher. Each case
    lasts until the controller shows it took its states (ros2_control_peer.effort_controller): its
    commands are then those of the postures sent so far, and its own posture's among them."""
    order = ["joint3", "joint1", "joint4", "joint2"]
    ctl = {
        "input_mode": "torque",
        "command_output": "effort_forward",
        "effort_command_joints": order,
        "control_rate": 100.0,
    }
    env = isolated_env()
    process = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    try:
        seen = _peer(["effort-controller", "0"], env)
    finally:
        log = _stop(process)
    commands = seen["commands"]
    assert seen["publisher_reliability"] == ["RELIABLE"]
    from bracing_core.controller_config import ControllerConfig
    from bracing_core.law import DecoupledController

    law = DecoupledController(ControllerConfig.from_params(node_params("bracing_controller", own=ctl, shared={})))
    expected = []  # each good posture's command, in the order the controller took them
    for q in seen["postures"][:4]:
        tau = law.update(0.0, np.array(q), np.zeros(4)).command
        expected.append(np.array([tau[JOINTS.index(j)] for j in order]))

    def posture(command: list[float]) -> int:
        """Which good posture's state the command answers (-1: none)."""
        matches = [k for k, tau in enumerate(expected) if np.allclose(command, tau, rtol=0, atol=1e-12)]
        return matches[0] if matches else -1

    answered = {case: [posture(c) for c in got] for case, got in commands.items()}
    assert answered["broadcaster"] and set(answered["broadcaster"]) == {0}, (answered, log)
    assert 1 in answered["sensor_data"], (answered, log)  # a SensorDataQoS publisher is served too
    assert 2 in answered["nan"] and 3 in answered["missing"], (answered, log)  # each case ran to its end
    for case, last in (("sensor_data", 1), ("nan", 2), ("missing", 3)):
        assert set(answered[case]) <= set(range(last + 1)), (case, answered, log)  # no command from a bad state
    assert seen["refused"] == []  # nothing the forward controller drops or errors on
    assert "joint_states refused: non-finite position or velocity" in log
    assert "joint_states refused: missing joints ['joint4']" in log


def test_hand_target_mid_run_moves_the_hand_there(tmp_path: Path) -> None:
    """The paper scenario (voltage, braced) in lockstep; at t = 1 s a script sends hand_target
    (0, 1.0, 0.7), after three the controller must refuse (out of reach, frame base_link, NaN). The
    reference goes there at <= 0.3 m/s and 1.5 m/s^2 (~0.25 m from the circle: ~1 s). Stated settling
    time 2.5 s: from then on the desired hand is the target exactly, and the hand is within 5 mm of
    where the same law holds that point when the YAML asks for it from the start (the paper's law, with
    no integral action, holds a point a few cm off it: that offset is the law's, not the target's)."""
    target, t_pub, settle, duration = [0.0, 1.0, 0.7], 1.0, 2.5, 4.0
    sim = {"duration": duration, "min_subscribers": 2}  # the controller and the script
    ctl = {"targets.max_velocity": 0.3, "targets.max_acceleration": 1.5}
    env = isolated_env()
    controller = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    simulator = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        seen = _peer(["target", str(t_pub), *map(str, target)], env)
        simulator.wait(60)
    finally:
        sim_log, ctl_log = _stop(simulator), _stop(controller)
    rows = np.array(seen["rows"])
    assert seen["sent_at"], sim_log + ctl_log
    assert "hand_target refused: out of reach" in ctl_log
    assert "hand_target refused: frame 'base_link'" in ctl_log
    assert "hand_target refused: not finite" in ctl_log
    sent = seen["sent_at"][0]
    settled = rows[rows[:, 0] >= sent + settle]
    assert len(settled) > 100, "the run ended before the settling time"
    np.testing.assert_allclose(settled[:, 1:4], np.tile(target, (len(settled), 1)), rtol=0, atol=1e-12)
    held = build_scenario(ctl={"hand.trajectory.type": "hold", "hand.trajectory.point": target})
    from bracing_core.rollout import run_recorded

    recording = run_recorded(held, duration)
    where = recording.hand_actual[-1]
    error = np.abs(settled[:, 5:7] - where[1:])
    assert error.max() < 5e-3, (error.max(), where)
    speeds = np.linalg.norm(np.diff(rows[:, 1:4], axis=0), axis=1) / 0.001
    assert speeds[rows[1:, 0] > sent + 0.01].max() <= 0.3 + 1e-9


def _start_recorder(bag: Path, env: dict[str, str]) -> subprocess.Popen[str]:
    argv = [sys.executable, "-m", "bracing_recorder.command", "--output", str(bag), "--contacts", "elbow", "--no-scene"]
    recorder = start(argv, env)
    assert recorder.stdout is not None
    for line in recorder.stdout:  # prints it once every subscription exists
        if "recorder ready" in line:
            return recorder
    raise AssertionError("the recorder ended before it was ready")


def test_hand_path_and_brace_target_mid_run_recorded_and_drawn(tmp_path: Path) -> None:
    """The paper scenario in lockstep, recorded. At t = 0.5 s a script sends a nav_msgs/Path on
    hand_path (poses stamped 1.5 s and 2.5 s: hold the first, then 0.05 m/s to the second) and moves
    the elbow's brace point 2 cm along y on brace_target/elbow. The reference (<= 0.3 m/s, 1.5 m/s^2)
    reaches the path's first pose ~1 s after it is sent (0.25 m away), so from 2.0 s it rides the path:
    the desired hand is the path's interpolation to 0.1 mm (it corrects a_max dt = 1.5 mm/s a step),
    the last pose exactly from 3.0 s; the desired brace point is the target exactly 1 s after the
    controller took it (0.02 m takes ~0.25 s). The bag holds one message per target, at the sim time it came, and the
    controller's echo of each (accepted); the hand figure marks the path's poses at their stamps."""
    from bracing_analysis.bag import read_series
    from bracing_analysis.figures import plot_figure
    from bracing_core.targets import path_goal
    from bracing_view.view import write_rrd

    poses = [[1.5, 0.0, 1.0, 0.7], [2.5, 0.0, 1.05, 0.72]]
    t_pub, dy, duration = 0.5, 0.02, 3.5
    env = isolated_env()
    bag = tmp_path / "bag"
    recorder = _start_recorder(bag, env)
    # wait_for_recorder: the controller takes no state before the recorder has matched it (its echoes are
    # volatile: one sent before the recorder's reader matched its writer would be lost to the bag)
    ctl = {"targets.max_velocity": 0.3, "targets.max_acceleration": 1.5, "wait_for_recorder": True}
    controller = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    # joint_states' subscribers: the controller, the recorder and the script (2 let a loaded machine start the
    # run before the script listened: it then sent its path late, in the past)
    sim = {"duration": duration, "wait_for_recorder": True, "min_subscribers": 3}
    simulator = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        seen = _peer(["path", str(t_pub), json.dumps(poses), str(dy)], env)
        simulator.wait(60)
    finally:
        sim_log, ctl_log = _stop(simulator), _stop(controller)
        recorder.send_signal(2)  # SIGINT: drained and closed
        rec_log = recorder.communicate(timeout=60)[0]
    assert seen["sent"], sim_log + ctl_log
    rows = np.array(seen["rows"])
    t, sent = rows[:, 0], seen["sent"][0]
    # When the controller took each target (its echo's stamp), after it was sent: the path early enough for
    # its reference (~1 s to reach the first pose) to ride it from 2.0 s, which a script lagging the run
    # by 0.5 s of sim time would miss.
    taken_path, taken_brace = seen["taken"]["hand_path/accepted"], seen["taken"]["brace_target/elbow/accepted"]
    assert sent[0] < taken_path <= 1.0 and sent[0] < taken_brace, (sent[0], seen["taken"])
    goal = path_goal([p[0] for p in poses], [np.array(p[1:]) for p in poses])
    riding = rows[(t >= 2.0) & (t <= 2.5)]
    expected = np.array([goal.at(tk)[0] for tk in riding[:, 0]])
    assert np.abs(riding[:, 1:4] - expected).max() < 1e-4
    np.testing.assert_array_equal(rows[t >= 3.0][:, 1:4], np.tile(poses[-1][1:], ((t >= 3.0).sum(), 1)))
    braced = rows[t >= taken_brace + 1.0]
    np.testing.assert_array_equal(braced[:, 7:10], np.tile(sent[1:], (len(braced), 1)))
    assert "hand_path: 2 poses from t = 1.500 s to 2.500 s" in ctl_log
    # the bag, the report
    series = read_series(bag)
    assert series.topic_counts["/hand_path"] == 1 and series.topic_counts["/brace_target/elbow"] == 1, rec_log
    accepted = series.topic_counts["/hand_path/accepted"], series.topic_counts["/brace_target/elbow/accepted"]
    assert accepted == (1, 1) and not series.targets_refused, rec_log
    hand, elbow = sorted(series.targets, key=lambda s: s.task)[::-1]
    assert (hand.task, elbow.task) == ("hand", "elbow")
    np.testing.assert_array_equal(hand.points, [p[1:] for p in poses])
    np.testing.assert_allclose(hand.times, [1.5, 2.5], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(elbow.points, [sent[1:]])
    for target in (hand, elbow):  # recorded at the sim time it came (the last /clock the recorder had got then:
        assert 0.0 < target.t < duration, target.t  # no bound tighter than the run, /clock and echo race)
    figure = plot_figure("hand_y", series)
    marks = [line for line in figure.axes[0].lines if line.get_label() == "hand_target / hand_path accepted"]
    assert len(marks) == 1 and list(marks[0].get_xdata()) == pytest.approx([1.5, 2.5])
    assert list(marks[0].get_ydata()) == [1.0, 1.05]
    # bracing-view draws them too: the path's poses joined, the brace target a point
    counts = write_rrd(bag, tmp_path / "run.rrd")
    assert counts.get("world/targets/hand") == 1 and counts.get("world/targets/hand/path") == 1, counts
    assert counts.get("world/targets/elbow") == 1, counts


def test_effort_forward_under_use_sim_time_follows_clock(tmp_path: Path) -> None:
    """effort_forward with use_sim_time at control_rate 100 Hz: while /clock stands still (1 s of wall
    time) at most one command goes out (the jump from 0 to 5 s); while it advances 10 ms a tick for 50
    ticks (0.5 s of sim time; each tick once the one before was answered, however long a loaded machine
    takes), one per tick: 50 (+-2 at the phase edges). A wall-clock timer would send ~100 in the frozen
    second; a timer of another period, or one that merged ticks, other than 50."""
    ctl = {"input_mode": "torque", "command_output": "effort_forward", "control_rate": 100.0, "use_sim_time": True}
    env = isolated_env()
    process = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    try:
        seen = _peer(["sim-clock"], env)
    finally:
        # Terminated with /clock stopped: the node still hears it (its executor waits 0.1 s at a time) and ends.
        process.terminate()
        log = process.communicate(timeout=30)[0]
    assert process.returncode == 0, log
    assert seen["frozen"] <= 2, (seen, log)
    assert 48 <= seen["advancing"] <= 52, (seen, log)


def test_free_run_voltage_drive_under_joint_state_efforts(tmp_path: Path) -> None:
    """The simulator in voltage mode (the paper's motors) under one held JointState effort command,
    stepping free_run: /clock goes out once per 1 ms step, every one; the current loop (10 ms) makes
    the motor torque K_m i the request within 1 % after 0.2 s (hand check: e^(-20) of the step left;
    the joints' motion is fed forward as back-EMF; the link-side effort differs by the motors'
    friction); energy is drawn (energy_consumed >= copper_loss > 0)."""
    tau = [3.0, -2.0, 1.0, 0.5]
    duration = 0.3
    sim = {"command_source": "joint_commands", "stepping": "free_run", "duration": duration}
    env = isolated_env()
    process = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        seen = _peer(["constant-effort", json.dumps(tau)], env)
    finally:
        log = _stop(process)
    clock = np.array(seen["clock"])
    np.testing.assert_allclose(clock, np.arange(round(duration / 0.001) + 1) * 0.001, rtol=0, atol=1e-12)
    currents = np.array(seen["current"])
    late = currents[currents[:, 0] >= 0.2][:, 1:]
    assert len(late) > 90, log
    constant = build_scenario(with_controller=False).plant.motors.reflected_constant  # K_m [N m/A], link side
    np.testing.assert_allclose(late * constant, np.tile(tau, (len(late), 1)), rtol=0.01, atol=0.0)
    # The state on /robot_joint_states, once per step: every step from the first one heard to the last (free_run
    # waits for no subscriber, so a loaded machine may match this one a few steps after /clock's).
    stamps = np.array([effort[0] for effort in seen["efforts"]])
    assert len(stamps) > len(clock) // 2, log
    np.testing.assert_allclose(stamps, clock[len(clock) - len(stamps) :], rtol=0, atol=1e-12)
    energy = np.array(seen["energy"])
    assert energy[-1, 1] >= energy[-1, 2] > 0.0
