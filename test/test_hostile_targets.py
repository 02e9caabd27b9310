"""Targets while running, sent by a careless or hostile peer: paths in the past or 56 years ahead, a
100,000-pose path, a 100,000-character frame name, floods. Refused with their reason before any
per-pose work, the latest of a flood followed (at most one target per topic per state), accepted ones
logged and echoed once per change, refused ones counted in summary.json and its warnings, and only the
accepted ones drawn.

The policy without DDS (bracing_core.targets, the raw Path peek), then one lockstep run with a recorder
and test/hostile_targets_peer.py over real DDS."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import build_scenario
from ros_helpers import REPO_ROOT, isolated_env, node_argv, params_file, start
from test_ros2_control import _start_recorder, _stop

from bracing_core.checks import frame_reach
from bracing_core.targets import TargetError, TargetLimits, TaskSpec, TaskTargets

PEER = str(REPO_ROOT / "test" / "hostile_targets_peer.py")
TARGET = [0.0, 1.0, 0.7]  # [m] within the paper arm's reach


def hand_targets(limits: TargetLimits | None = None) -> TaskTargets:
    """The paper arm's hand task (axes y, z), with its reach (the default limits unless ``limits``)."""
    plant = build_scenario(with_controller=False).plant
    reach = frame_reach(plant.robot.model, plant.frame_id("hand", "hand.frame"))
    return TaskTargets([TaskSpec("hand_target", (1, 2), reach)], 0.3, 1.5, limits or TargetLimits())


def refusal(call: object, *args: object, **kwargs: object) -> TargetError:
    with pytest.raises(TargetError) as caught:
        call(*args, **kwargs)  # type: ignore[operator]
    return caught.value


def test_paths_in_the_past_or_past_the_horizon_are_refused_with_their_reason() -> None:
    """now = 2 s: a path ending at 1.9 s is entirely in the past; one ending 56 years on (a wall-clock
    stamp) lies past targets.max_horizon (default 3600 s); one ending at now, or at now + the horizon,
    is taken. Nothing refused changes the goal."""
    targets = hand_targets()
    frames = ["world", "world"]
    past = refusal(targets.path, 0, [1.5, 1.9], [TARGET, TARGET], frames, now=2.0)
    assert past.kind == "in the past" and "entirely in the past" in str(past) and str(past).startswith("hand_path")
    ahead = refusal(targets.path, 0, [2.0, 1.77e9], [TARGET, TARGET], frames, now=2.0)
    assert ahead.kind == "too far ahead" and "targets.max_horizon = 3600 s" in str(ahead)
    assert not targets.goals
    assert targets.path(0, [1.0, 2.0], [TARGET, TARGET], frames, now=2.0) is not None
    assert targets.path(0, [2.0, 3602.0], [TARGET, TARGET], frames, now=2.0) is not None
    short = hand_targets(TargetLimits(max_horizon=10.0))
    assert refusal(short.path, 0, [2.0, 12.5], [TARGET, TARGET], frames, now=2.0).kind == "too far ahead"


def test_sizes_are_refused_before_any_per_pose_work() -> None:
    """More poses than max_message_elements: refused as such though every pose is bad (no pose looked
    at); a frame name longer than max_name_length: refused, quoted at most 40 characters."""
    targets = hand_targets(TargetLimits(max_poses=100, max_name_length=16))
    nan = [float("nan")] * 3
    many = refusal(targets.path, 0, list(range(101)), [nan] * 101, ["base_link"] * 101, now=0.0)
    assert many.kind == "too many poses" and "101 poses, more than max_message_elements = 100" in str(many)
    long_name = "w" * 100_000
    named = refusal(targets.point, 0, TARGET, long_name)
    assert named.kind == "name too long" and len(str(named)) < 200
    assert refusal(targets.path, 0, [1.0], [TARGET], [long_name], now=0.0).kind == "name too long"
    assert refusal(hand_targets().point, 0, TARGET, long_name).kind == "name too long"  # the default, 256
    frame = refusal(hand_targets().point, 0, TARGET, "x" * 200)  # within the limit, another frame: quoted cut
    assert frame.kind == "frame" and "(200 characters)" in str(frame) and len(str(frame)) < 200


def test_the_same_target_again_is_no_change() -> None:
    """What the node logs and echoes once per change: a goal equal to the current one is None."""
    targets = hand_targets()
    assert targets.point(0, TARGET, "world") is not None
    assert targets.point(0, list(TARGET), "world") is None
    assert targets.point(0, [0.0, 1.0, 0.71], "world") is not None
    assert targets.path(0, [1.0, 2.0], [TARGET, TARGET], ["world", "world"], now=0.0) is not None
    assert targets.path(0, [1.0, 2.0], [TARGET, TARGET], ["world", "world"], now=0.5) is None


def test_a_path_is_measured_from_its_first_bytes() -> None:
    """path_sizes reads the frame name's length and the pose count of a Path as rclpy serialises it, and
    needs no pose bytes at all: a 100,000-pose count with the poses cut off is still read."""
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path as PathMsg
    from rclpy.serialization import serialize_message

    from bracing_ros.raw_messages import path_sizes

    for frame, poses in (("world", 3), ("", 0), ("abc", 1), ("w" * 1000, 2)):
        path = PathMsg()
        path.header.frame_id = frame
        path.header.stamp = Time(sec=7, nanosec=5)
        path.poses = [PoseStamped() for _ in range(poses)]
        data = serialize_message(path)
        assert path_sizes(data) == (len(frame), poses)
    big = PathMsg()
    big.header.frame_id = "world"
    big.poses = [PoseStamped() for _ in range(3)]
    head = bytearray(serialize_message(big))
    at = 4 + 8 + 4 + len("world") + 1
    at += -at % 4
    head[at : at + 4] = (100_000).to_bytes(4, "little")
    assert path_sizes(bytes(head[: at + 4])) == (5, 100_000)


# -- over DDS -----------------------------------------------------------------------------------------
def test_hostile_targets_refused_counted_and_never_drawn(tmp_path: Path) -> None:
    """The paper scenario in lockstep (6 s: the peer, which lags the run, takes up to ~3.5 s for its steps),
    recorded, with test/hostile_targets_peer.py sending its seven steps (see there). The controller:
    the same target 100 times logged and echoed once; the four bad paths refused, each with its reason;
    every state answered; of a flood of 2,000 targets, at most one taken per state (each echo's stamp
    a different state's) and the law following the last one sent; the flood in another frame refused
    as many times as taken, not as sent. The summary counts the refusals per topic and quotes the first
    of each kind once; the report draws only what was accepted."""
    from bracing_analysis.bag import read_series
    from bracing_analysis.figures import plot_figure
    from bracing_analysis.summary import compute_summary

    flood_dy, duration = -0.03, 6.0
    env = isolated_env()
    bag = tmp_path / "bag"
    recorder = _start_recorder(bag, env)
    ctl = {"targets.max_velocity": 0.3, "targets.max_acceleration": 1.5}
    controller = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    sim = {"duration": duration, "wait_for_recorder": True, "min_subscribers": 3}  # controller, recorder, peer
    simulator = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        argv = [sys.executable, PEER, *map(str, TARGET), str(flood_dy)]
        peer = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=240)
        simulator.wait(60)
    finally:
        sim_log, ctl_log = _stop(simulator), _stop(controller)
        recorder.send_signal(2)  # SIGINT: drained and closed
        rec_log = recorder.communicate(timeout=60)[0]
    assert peer.returncode == 0, peer.stdout + peer.stderr
    seen = json.loads(peer.stdout.strip().splitlines()[-1])
    assert seen.get("steps_done") == 7, (seen.get("steps_done"), ctl_log[-3000:])
    # logged once per change, bounded
    assert ctl_log.count("hand_target: moving to [0, 1, 0.7] and holding it") == 1, ctl_log[-3000:]
    target_lines = [line for line in ctl_log.splitlines() if "hand_target" in line or "hand_path" in line]
    assert len(target_lines) <= 20, target_lines  # 2,600 targets sent
    # refused with their reason, at most one per state
    kinds = [(r["topic"], r["kind"]) for r in seen["refused"]]
    paths = [kind for topic, kind in kinds if topic == "hand_path"]
    assert paths == ["in the past", "too far ahead", "too many poses", "name too long"], kinds
    frames = [r for r in seen["refused"] if r["topic"] == "hand_target"]
    assert {r["kind"] for r in frames} == {"frame"}
    refused_frames = frames[-1]["count"]
    assert 1 <= refused_frames < 400, refused_frames  # 400 sent
    # (its refusal reaches the peer ~0.5-0.9 s after the peer began to send it: most of that is its own
    # serialisation of 8 MB; the controller refuses it on its first bytes: test_a_path_is_measured_from_its_first_bytes)
    # the flood: at most one taken per state, the last one followed
    accepted = np.array(seen["accepted"])
    assert accepted[0, :3].tolist() == TARGET
    stamps = accepted[:, 3]
    assert len(np.unique(stamps)) == len(stamps), "two targets of one topic taken at one state"
    final = [TARGET[0], TARGET[1] + flood_dy, TARGET[2]]
    assert accepted[-1, :3].tolist() == final
    rows = np.array(seen["rows"])
    # <= 0.3 m/s and 1.5 m/s^2 from the configured circle to the first target (0.32 m: ~1.4 s), 3 cm more to
    # the last (~0.3 s): stated settling time 2 s after the first is taken, and 0.5 s after the last
    settle_from = max(accepted[0, 3] + 2.0, accepted[-1, 3] + 0.5)
    settled = rows[rows[:, 0] >= settle_from]
    assert len(settled) > 100, f"the run ended before the flood's last target was reached ({settle_from:.3f} s)"
    np.testing.assert_array_equal(settled[:, 1:4], np.tile(final, (len(settled), 1)))
    # every state answered (a 100,000-pose path stalls nothing), the bag, the summary, the report
    series = read_series(bag)
    assert len(series.t) == len(series.joint_t) == round(duration / 0.001) + 1, rec_log + sim_log[-2000:]
    summary = compute_summary(series)
    assert summary["targets_refused"] == {"hand_path": 4, "hand_target": refused_frames}
    refusals = [w for w in summary["warnings"] if " refused" in w]
    assert len(refusals) == 5, summary["warnings"]
    assert any(w.startswith("hand_path refused: entirely in the past") and " 1 hand_path " in w for w in refusals)
    assert any(f" {len(frames)} hand_target target(s) refused" in w for w in refusals), refusals
    assert {s.task for s in series.targets} == {"hand"}
    drawn = np.concatenate([s.points for s in series.targets])
    assert drawn[:, 1].min() >= final[1] - 1e-12 and drawn[:, 1].max() <= TARGET[1] + 1e-12
    figure = plot_figure("hand_y", series)
    marks = [line for line in figure.axes[0].lines if line.get_label() == "hand_target / hand_path accepted"]
    assert marks, [line.get_label() for line in figure.axes[0].lines]
    for mark in figure.axes[0].lines[2:]:
        x, y = np.asarray(mark.get_xdata(), dtype=float), np.asarray(mark.get_ydata(), dtype=float)
        assert x.max() <= duration and y.max() <= TARGET[1] + 1e-12, (x.max(), y.max())


def test_effort_forward_takes_targets_at_its_control_rate(tmp_path: Path) -> None:
    """command_output effort_forward (targets taken by the executor, checked at the next tick): a path in
    the past (the states stamped 10 s) refused with its reason, then a target accepted."""
    ctl = {"input_mode": "torque", "command_output": "effort_forward", "control_rate": 100.0}
    env = isolated_env()
    controller = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    try:
        argv = [sys.executable, PEER, "effort", *map(str, TARGET)]
        peer = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=120)
    finally:
        log = _stop(controller)
    assert peer.returncode == 0, peer.stdout + peer.stderr
    verdicts = json.loads(peer.stdout.strip().splitlines()[-1])["verdicts"]
    assert [v[0] for v in verdicts] == ["refused", "accepted"], (verdicts, log)
    assert verdicts[0][1].startswith("hand_path refused: entirely in the past"), verdicts
    assert "hand_target: moving to [0, 1, 0.7] and holding it" in log
