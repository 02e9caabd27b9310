"""A mobile base over real DDS: the simulator publishes odom (nav_msgs/Odometry) for the hand-built planar base
of test/data/planar_base_arm.urdf, the controller (base_command cmd_vel) takes cmd_vel (geometry_msgs/TwistStamped)
from a teleop process while it braces the elbow, the recorder keeps both; read back from the bag."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_helpers import REPO_ROOT, isolated_env, params_file, start
from rosbags.highlevel import AnyReader
from test_ros2_control import _start_recorder, _stop

STAND_IN = Path(__file__).parent / "data" / "planar_base_arm.yaml"
PEER = str(REPO_ROOT / "test" / "cmd_vel_peer.py")
SPEED, START_S, STOP_S, DURATION_S = 0.1, 0.6, 1.4, 2.8


def node_argv(module: str, own: Path) -> list[str]:
    return [sys.executable, "-m", module, "--ros-args", "--params-file", str(STAND_IN), "--params-file", str(own)]


def _stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def read_bag(bag: Path) -> dict[str, list[Any]]:
    wanted = {"/odom", "/joint_states", "/cmd_vel", "/contacts"}
    out: dict[str, list[Any]] = {topic: [] for topic in wanted}
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic in wanted]
        for connection, _, raw in reader.messages(connections=connections):
            out[connection.topic].append(reader.deserialize(raw, connection.msgtype))
    return out


@pytest.fixture(scope="module")
def driven(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, list[Any]], dict[str, Any], str]:
    """The stand-in run 2.8 s in lockstep, recorded, test/cmd_vel_peer.py sending a NaN at 0.6 s, a stale one at
    0.7 s, then 0.1 m/s from 0.8 s to 1.4 s."""
    tmp = tmp_path_factory.mktemp("mobile")
    env = isolated_env()
    bag = tmp / "bag"
    recorder = _start_recorder(bag, env)
    urdf = str(STAND_IN.parent / "planar_base_arm.urdf")
    ctl = {"robot.urdf": urdf, "base_command": "cmd_vel", "wait_for_recorder": True, "null_space_posture.kd": [0.0] * 7}
    controller = start(node_argv("bracing_controller.node", params_file(tmp, "bracing_controller", ctl)), env)
    sim = {"robot.urdf": urdf, "duration": DURATION_S, "wait_for_recorder": True, "min_subscribers": 3}
    simulator = start(node_argv("bracing_sim.node", params_file(tmp, "bracing_simulator", sim)), env)
    try:
        peer = subprocess.run(
            [sys.executable, PEER, str(SPEED), str(START_S), str(STOP_S)],
            env=env, capture_output=True, text=True, timeout=240,
        )  # fmt: skip
        simulator.wait(120)
    finally:
        _stop(simulator)
        ctl_log = _stop(controller)
        recorder.send_signal(2)  # SIGINT: drained and closed
        recorder.communicate(timeout=60)
    assert peer.returncode == 0, peer.stdout + peer.stderr
    return read_bag(bag), json.loads(peer.stdout.strip().splitlines()[-1]), ctl_log


def test_odom_is_the_base_pose_and_integrates_its_twist(driven: tuple[dict[str, list[Any]], Any, str]) -> None:
    topics, _, _ = driven
    odom, states = topics["/odom"], topics["/joint_states"]
    assert len(odom) == len(states) == round(DURATION_S / 0.001) + 1
    assert {(m.header.frame_id, m.child_frame_id) for m in odom} == {("odom", "cart")}
    pose = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, 2 * math.atan2(m.pose.pose.orientation.z,
                      m.pose.pose.orientation.w)] for m in odom])  # fmt: skip
    names = list(states[0].name)
    index = [names.index(j) for j in ("base_x", "base_y", "base_yaw")]
    joints = np.array([[m.position[i] for i in index] for m in states])
    assert [_stamp(m) for m in odom] == [_stamp(m) for m in states]
    assert np.abs(pose - joints).max() < 1e-15  # the pose is the base's, exactly
    # the twist, in the root link's frame, turned into the world and integrated (trapezoid), is the pose's path
    twist = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.angular.z] for m in odom])
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    world = np.stack([c * twist[:, 0] - s * twist[:, 1], s * twist[:, 0] + c * twist[:, 1], twist[:, 2]], axis=1)
    integrated = pose[0] + np.concatenate([np.zeros((1, 3)), np.cumsum(0.0005 * (world[1:] + world[:-1]), axis=0)])
    # to the trapezoid's error over 1 ms steps (RK4 inside; the elbow's stick-slip kicks the yaw rate): 2e-7 m and
    # 4e-6 rad measured over the 2.8 s
    assert np.abs(integrated - pose)[:, :2].max() < 1e-6 and np.abs(integrated - pose)[:, 2].max() < 1e-5
    assert pose[-1, 0] > 0.05  # it moved
    assert all(m.pose.covariance[0] == 0.0 and m.twist.covariance[35] == 0.0 for m in odom[:3])


def test_cmd_vel_moves_the_base_while_the_brace_holds(driven: tuple[dict[str, list[Any]], Any, str]) -> None:
    topics, peer, ctl_log = driven
    sent = peer["sent"]
    assert len(sent) == 7 and len(topics["/cmd_vel"]) == 9  # the recorder kept what the controller was sent
    states = topics["/joint_states"]
    names = list(states[0].name)
    t = np.array([_stamp(m) for m in states]) * 1e-9
    x = np.array([m.position[names.index("base_x")] for m in states])
    speed = np.array([m.velocity[names.index("base_x")] for m in states])
    f_n = np.array([m.contacts[0].normal_force for m in topics["/contacts"]])
    # the velocity loop (kd 100 N s/m) takes the base up toward 0.1 m/s less what the braced elbow's friction
    # costs (mu f_nd / kd = 0.01 m/s at most: test_base_command), from rest when the first cmd_vel comes
    driving = (t > sent[0] + 0.01) & (t < sent[-1])
    assert abs(speed[t < sent[0]]).max() < 2e-3
    assert 0.08 < speed[driving][-1] and speed[driving].max() < 0.0915
    # the elbow at f_nd to rounding while it slides (the arm takes up what the base's loop would lean on it)
    sliding = (t > sent[0] + 0.01) & (t < sent[-1] + 0.5)
    assert np.abs(f_n[sliding[: f_n.size]] - 10.0).max() < 1e-9
    assert np.abs(f_n - 10.0).max() < 0.3  # where it sticks, eq. 40's sliding friction is not the floor's
    assert x[-1] > 0.05 and abs(speed[-1]) < 2e-3  # braked 0.5 s after the last cmd_vel
    assert "cmd_vel ignored: linear.x, linear.y, angular.z must be finite" in ctl_log  # a planar base uses linear.y
    assert "past cmd_vel_timeout 0.5 s" in ctl_log
    assert "cmd_vel timed out at t = " in ctl_log
