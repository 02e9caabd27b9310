"""hand_pose_target (geometry_msgs/PoseStamped): the hand's position and the orientation task's target moved
without a kick, its refusals; the orientation error over ROS (hand_orientation_error), recorded, in the
summary and the report. The policy without DDS (bracing_core.targets, bracing_core.answering), then the nodes."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import build_scenario, node_params
from ros_helpers import PAPER_YAML, REPO_ROOT, isolated_env, node_argv, pair_argv, params_file, run, start
from test_lab_control import (
    ACCELERATION,
    HELD,
    NO_BRACE_TASK,
    PAPER,
    TORQUE,
    TURNABLE,
    _hand_rotation,
    _quaternion,
    hand_start,
)
from test_lab_control import _rotation as rotation
from test_ros2_control import _start_recorder, _stop
from test_stepping import Clock, Log

from bracing_core.answering import Answer, StateAnswerer
from bracing_core.checks import frame_reach
from bracing_core.targets import (
    OrientationReference,
    OrientationSpec,
    TargetError,
    TaskSpec,
    TaskTargets,
)
from bracing_experiments.experiment import execute_run
from bracing_experiments.sweep import build_specs

PEER = str(REPO_ROOT / "test" / "pose_target_peer.py")
W = 2.0 * np.pi  # [rad/s] the tasks' bandwidth (acceleration gains, poles at -W)
TURN = {
    **HELD,
    **ACCELERATION,
    **NO_BRACE_TASK,
    "hand.kp": [3 * W**2] * 2,
    "hand.kd": [3 * W] * 2,
    "hand.ki": [W**3] * 2,
    "hand.trajectory.type": "hold",
    "hand.orientation.axes": ["x"],
    "hand.orientation.kp": [3 * W**2],
    "hand.orientation.kd": [3 * W],
    "hand.orientation.ki": [W**3],
}
"""The paper arm turning its hand about x (the plane's normal) as well, from a posture where it can
(test_lab_control's TURNABLE), its elbow's position task dropped: three task rows for n - p = 3."""
STEP_NS = 1_000_000  # the paper's 1 ms step
MAX_TURN = 0.5  # [rad/s] targets.max_angular_velocity's default


def pose_targets(orientation_axes: tuple[int, ...] = (0,)) -> TaskTargets:
    scenario = build_scenario()
    robot = scenario.plant.robot
    reach = frame_reach(robot.model, robot.frame_id("hand"))
    return TaskTargets(
        [TaskSpec("hand_target", (1, 2), reach)], 0.05, 0.2, orientation=OrientationSpec(orientation_axes)
    )


def refusal(targets: TaskTargets, point: list[float], quaternion: list[float], frame: str = "world") -> TargetError:
    with pytest.raises(TargetError) as caught:
        targets.pose(point, quaternion, frame)
    assert caught.value.args[0].startswith("hand_pose_target refused: ")
    return caught.value


def test_a_pose_target_is_refused_with_its_reason() -> None:
    """Another frame, a non-finite position or orientation, a zero or far-from-unit quaternion, a position out of
    reach, and any pose without an orientation task (the message says which parameter to set); a near-unit
    quaternion is normalised; the same pose again is no change, a new orientation alone is one."""
    targets, point, unit = pose_targets(), [0.0, 1.0, 0.7], [0.0, 0.0, 0.0, 1.0]
    assert refusal(targets, point, unit, "base_link").kind == "frame"
    assert refusal(targets, [0.0, np.nan, 0.7], unit).kind == "not finite"
    assert refusal(targets, point, [0.0, 0.0, np.inf, 1.0]).kind == "not finite"
    assert refusal(targets, point, [0.0, 0.0, 0.0, 0.0]).kind == "not a rotation"
    far = refusal(targets, point, [0.0, 0.0, 0.0, 1.5])
    assert far.kind == "not a rotation" and "norm 1.5" in str(far)
    assert refusal(targets, [0.0, 9.0, 0.7], unit).kind == "out of reach"
    none = refusal(pose_targets(()), point, unit)
    assert none.kind == "no orientation task" and "set hand.orientation.axes" in str(none)
    assert not targets.goals and targets.orientation_goal is None  # nothing refused was taken
    near = [0.0, 0.0, np.sin(0.1), 1.004 * np.cos(0.1)]  # norm ~1.004: normalised
    goal = targets.pose(point, near, "world")
    assert goal is not None and goal.points[0].tolist() == point
    turn = pin.Quaternion(near[3], *near[:3]).normalized().toRotationMatrix()
    assert targets.orientation_goal == pytest.approx(turn, abs=1e-15)
    assert targets.pose(point, near, "world") is None  # no change
    assert targets.pose(point, unit, "world") is not None  # the orientation alone changed


def test_the_orientation_reference_turns_without_a_kick() -> None:
    """From the held rotation at rest toward a goal 1 rad away: the angular velocity starts at zero, changes by
    at most alpha dt per step and never exceeds w_max; each step turns R_d by at most w_max dt; the goal is
    reached exactly (then held)."""
    start = rotation(np.array([0.0, 0.6, 0.8]), 0.3)
    goal = rotation(np.array([1.0, 0.0, 0.0]), 1.0) @ start
    w_max, alpha, dt = 0.5, 2.0, 1e-3
    reference = OrientationReference(start, 0.0, w_max, alpha)
    reference.goal = goal
    previous_r, previous_w = start, np.zeros(3)
    for k in range(1, 4000):
        r, w = reference.advance(k * dt)
        assert np.linalg.norm(w) <= w_max + 1e-12
        assert np.linalg.norm(w - previous_w) <= alpha * dt + 1e-12
        assert np.linalg.norm(pin.log3(r @ previous_r.T)) <= w_max * dt + 1e-12
        previous_r, previous_w = r.copy(), w.copy()
    assert np.array_equal(previous_r, goal) and not previous_w.any()


def run_in_process(duration_s: float, pose_at_s: float, pose: list[float]) -> tuple[list[Answer], list[np.ndarray]]:
    """The controller node's policy (StateAnswerer) and the simulator in lockstep, in process: the pose taken
    at ``pose_at_s``; every answer and the law's R_d after each."""
    scenario = build_scenario(TORQUE, sim=TURNABLE, ctl=TURN)
    assert scenario.controller is not None
    core, sim = StateAnswerer(scenario.controller.config, Log(), Clock()), scenario.sim
    sent: list[Answer] = []
    held: list[np.ndarray] = []
    for k in range(round(duration_s * 1e9 / STEP_NS)):
        if k == round(pose_at_s * 1e9 / STEP_NS):
            assert core.targets.pose(pose[:3], pose[3:], "world") is not None
        core.answer(k * STEP_NS, sim.position, sim.velocity, lambda _: None, sent.append)
        held.append(np.asarray(core.law.engine.orientation_reference()))
        sim.step(sent[-1].output.command)
    return sent, held


def held_pose() -> list[float]:
    """1 cm along y from the hand's start, turned 0.05 rad about x from its start orientation."""
    point = hand_start(PAPER, TURNABLE) + np.array([0.0, 0.01, 0.0])
    turn = rotation(np.array([1.0, 0.0, 0.0]), 0.05) @ _hand_rotation(PAPER, TURNABLE)
    return [*point.tolist(), *_quaternion(turn)]


def test_a_held_pose_target_is_reached_without_a_kick() -> None:
    """The paper arm turning its hand (acceleration gains, 1 Hz): a hand_pose_target 1 cm and 0.05 rad away
    taken at 0.5 s; R_d starts where it was held (no jump) and turns at most max_angular_velocity; within 1 mm
    and 5 mrad of the pose from 3 s after it came."""
    pose = held_pose()
    sent, held = run_in_process(4.0, 0.5, pose)
    t = np.array([a.stamp_ns * 1e-9 for a in sent])
    steps = [float(np.linalg.norm(pin.log3(b @ a.T))) for a, b in itertools.pairwise(held)]
    assert max(steps) <= MAX_TURN * STEP_NS * 1e-9 + 1e-12 and max(steps) > 0.0
    assert held[499] == pytest.approx(held[0], abs=0.0)  # held until the pose came
    late = t >= 3.5
    hand = np.array([a.output.hand_actual for a in sent])
    assert np.linalg.norm(hand - np.array(pose[:3]), axis=1)[late].max() < 1e-3
    turn = np.array([a.output.orientation_error for a in sent])
    assert np.linalg.norm(turn, axis=1)[late].max() < 5e-3
    goal = pin.Quaternion(pose[6], *pose[3:6]).toRotationMatrix()
    assert np.array_equal(held[-1], goal)  # the reference ends on the pose's orientation


def test_a_retuned_orientation_target_is_turned_to_without_a_kick() -> None:
    """hand.orientation.target set while running (ros2 param set): turned to as a pose's orientation, R_d at
    most max_angular_velocity a step, within 5 mrad from 3 s after; emptied, or set without an orientation
    task, it is refused with the reason."""
    scenario = build_scenario(TORQUE, sim=TURNABLE, ctl=TURN)
    assert scenario.controller is not None
    core, sim = StateAnswerer(scenario.controller.config, Log(), Clock()), scenario.sim
    values = node_params("bracing_controller", TORQUE, TURN)
    goal = rotation(np.array([1.0, 0.0, 0.0]), 0.05) @ _hand_rotation(PAPER, TURNABLE)
    sent: list[Answer] = []
    held: list[np.ndarray] = []
    for k in range(4000):
        if k == 500:
            assert core.retune(dict(values), [("hand.orientation.target", _quaternion(goal))]) is None
        core.answer(k * STEP_NS, sim.position, sim.velocity, lambda _: None, sent.append)
        held.append(np.asarray(core.law.engine.orientation_reference()))
        sim.step(sent[-1].output.command)
    steps = [float(np.linalg.norm(pin.log3(b @ a.T))) for a, b in itertools.pairwise(held)]
    assert 0.0 < max(steps) <= MAX_TURN * STEP_NS * 1e-9 + 1e-12
    assert np.abs(held[-1] - goal).max() < 1e-12
    turn = np.array([a.output.orientation_error for a in sent])
    assert np.linalg.norm(turn, axis=1)[3500:].max() < 5e-3
    emptied = core.retune(dict(values), [("hand.orientation.target", [])])
    assert emptied is not None and "cannot be emptied while running" in emptied
    plain = StateAnswerer(build_scenario(TORQUE, ctl=HELD).controller.config, Log(), Clock())  # type: ignore[union-attr]
    refused = plain.retune(
        node_params("bracing_controller", TORQUE, HELD), [("hand.orientation.target", [0, 0, 0, 1.0])]
    )
    assert refused is not None and "set hand.orientation.axes" in refused


def _sets(pairs: dict[str, Any]) -> list[str]:
    return [f"{k}={json.dumps(v)}" for k, v in pairs.items()]


def test_the_pairs_orientation_error_is_the_in_process_runs(tmp_path: Path) -> None:
    """Over DDS (bracing-pair, record_batch): the controller publishes hand_orientation_error once per state,
    the recorder records it, summary.json's hand_orientation_rms_error_rad equals the in-process run's and the
    report draws it; the paper scenario's bag has no such topic."""
    from bracing_analysis.bag import read_series

    target = rotation(np.array([1.0, 0.0, 0.0]), 0.05) @ _hand_rotation(PAPER, TURNABLE)
    sets = _sets({**TORQUE, **TURN, "hand.orientation.target": _quaternion(target), **TURNABLE})
    out = tmp_path / "turn"
    done = run(
        pair_argv(out, "--duration", "2.3", "--no-animation", *(a for s in sets for a in ("--set", s))), timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    pair = json.loads((out / "summary.json").read_text())
    (spec,) = build_specs(PAPER_YAML, sets, zipped=False, duration=2.3)
    in_process = execute_run(spec).summary
    assert in_process is not None
    # the same engine and the same time (the states' stamps, engine.stamp_seconds, on both paths): bit for bit
    assert pair["hand_orientation_rms_error_rad"] == in_process["hand_orientation_rms_error_rad"]
    assert pair["hand_rms_error_m"] == in_process["hand_rms_error_m"]
    assert 0.0 < pair["hand_orientation_rms_error_rad"] < 5e-3  # from 2 s on (HAND_ERROR_T_MIN_S)
    series = read_series(out)
    assert series.hand_orientation_error.shape == (series.t.size, 3)
    assert (out / "hand_orientation.png").is_file()
    plain = tmp_path / "plain"
    done = run(pair_argv(plain, "--duration", "0.1", "--no-animation"), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    counts = read_series(plain).topic_counts
    assert not [topic for topic in counts if "orientation" in topic or "pose" in topic], counts
    assert json.loads((plain / "summary.json").read_text())["hand_orientation_rms_error_rad"] is None


def test_a_pose_target_over_ros_is_refused_counted_then_reached(tmp_path: Path) -> None:
    """The nodes in lockstep, recorded, test/pose_target_peer.py sending from 0.2 s: a pose in base_link and one
    with a zero quaternion (each refused with its kind, counted in summary.json), then the held pose (accepted,
    echoed normalised): the hand within 1 mm and 5 mrad of it from 3 s after (the bag's hand_orientation_error)."""
    from bracing_analysis.bag import read_series
    from bracing_analysis.summary import compute_summary

    pose, duration = held_pose(), 4.0
    env = isolated_env()
    bag = tmp_path / "bag"
    recorder = _start_recorder(bag, env)
    ctl = {**TORQUE, **TURN}
    controller = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    sim = {**TORQUE, **TURNABLE, "duration": duration, "wait_for_recorder": True, "min_subscribers": 3}
    simulator = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        peer = subprocess.run(
            [sys.executable, PEER, *map(str, pose)], env=env, capture_output=True, text=True, timeout=240
        )
        simulator.wait(120)
    finally:
        _stop(simulator)
        ctl_log = _stop(controller)
        recorder.send_signal(2)  # SIGINT: drained and closed
        recorder.communicate(timeout=60)
    assert peer.returncode == 0, peer.stdout + peer.stderr
    verdicts = json.loads(peer.stdout.strip().splitlines()[-1])["verdicts"]
    assert [v["verdict"] for v in verdicts] == ["refused", "refused", "accepted"], (verdicts, ctl_log[-2000:])
    assert [v["kind"] for v in verdicts[:2]] == ["frame", "not a rotation"]
    assert verdicts[2]["orientation"] == pytest.approx(pose[3:], abs=1e-12)
    series = read_series(bag)
    summary = compute_summary(series, 1.0)
    assert summary["targets_refused"] == {"hand_pose_target": 2}
    late = series.t >= verdicts[2]["t"] + 3.0
    assert late.sum() > 100
    assert np.linalg.norm(series.hand_actual - np.array(pose[:3]), axis=1)[late].max() < 1e-3
    assert np.linalg.norm(series.hand_orientation_error, axis=1)[late].max() < 5e-3
    assert [t.task for t in series.targets] == ["hand"]  # the accepted pose, drawn as the hand's target
