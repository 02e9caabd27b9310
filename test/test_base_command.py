"""A mobile base's ROS face without DDS (bracing_core.mobile_base): odometry from the base's state, cmd_vel
taken, refused and timed out as ros2_controllers' diff_drive_controller does, its wheels' inverse kinematics,
targets carried with the base; and, in process, the controller's policy (StateAnswerer) driving the hand-built
planar base of test/data/planar_base_arm.urdf under cmd_vel while the elbow stays braced."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_stepping import Clock, Log

from bracing_core.answering import Answer, StateAnswerer
from bracing_core.base import BASE_JOINTS, Wheels
from bracing_core.mobile_base import (
    BaseDrive,
    BaseFrame,
    BaseOdometry,
    BaseTwist,
    CmdVelGate,
    CmdVelRefused,
    base_indices,
    odometry,
    root_link,
    wheel_velocities,
    world_twist,
)
from bracing_core.params import ConfigError
from bracing_core.rollout import Scenario, build_scenario

STAND_IN = Path(__file__).parent / "data" / "planar_base_arm.yaml"
MS = 1_000_000  # [ns]


def test_odometry_is_the_base_pose_with_the_twist_in_the_root_link_s_frame() -> None:
    # heading 30 deg, moving (dx, dy) = (0.3, 0.4) m/s in the world, turning 0.2 rad/s
    names = ["joint1", "base_yaw", "base_x", "base_y"]
    indices = base_indices(names)
    assert indices == (2, 3, 1) and base_indices(names[:3]) is None
    position = np.array([9.0, math.pi / 6, 1.5, -2.0])
    velocity = np.array([9.0, 0.2, 0.3, 0.4])
    odom = odometry(position, velocity, indices)
    c, s = math.sqrt(3) / 2, 0.5
    assert (odom.x, odom.y, odom.yaw, odom.yaw_rate) == (1.5, -2.0, math.pi / 6, 0.2)
    assert odom.forward == pytest.approx(c * 0.3 + s * 0.4, abs=1e-15)  # 0.4598
    assert odom.left == pytest.approx(-s * 0.3 + c * 0.4, abs=1e-15)  # 0.1964
    assert odom.quaternion == pytest.approx((0.0, 0.0, math.sin(math.pi / 12), math.cos(math.pi / 12)), abs=1e-15)
    # the twist turned back into the world is the joints' velocities
    back = world_twist(BaseTwist(odom.forward, odom.left, odom.yaw_rate), odom.yaw)
    assert back == pytest.approx([0.3, 0.4, 0.2], abs=1e-15)


def test_wheel_speeds_are_diff_drive_controller_s_and_give_back_the_unicycle() -> None:
    r, s = 0.0985, 0.4044  # TIAGo's wheel radius and separation [m]
    left, right = wheel_velocities(0.5, 0.8, r, s)
    assert left == pytest.approx((0.5 - 0.8 * s / 2) / r, abs=1e-14)
    assert right == pytest.approx((0.5 + 0.8 * s / 2) / r, abs=1e-14)
    # forward kinematics of the unicycle: v = r (wl + wr) / 2, omega = r (wr - wl) / s
    assert r * (left + right) / 2 == pytest.approx(0.5, abs=1e-14)
    assert r * (right - left) / s == pytest.approx(0.8, abs=1e-14)
    assert wheel_velocities(0.0, 1.0, 0.1, 0.4) == pytest.approx((-2.0, 2.0), abs=1e-15)  # on the spot


def test_cmd_vel_is_refused_when_not_finite_or_stale_and_brakes_once_old() -> None:
    gate = CmdVelGate(0.5, holonomic=False)
    assert gate.command(0) == BaseTwist()  # none yet: at rest
    now = 2000 * MS
    twist = gate.offer(1900 * MS, [0.2, 5.0, 0.0], [0.0, 0.0, 0.1], now)
    assert twist == BaseTwist(0.2, 0.0, 0.1)  # linear.y ignored on a differential drive, as diff_drive_controller
    for linear, angular in [([math.nan, 0, 0], [0, 0, 0]), ([0.1, 0, 0], [0, 0, math.inf])]:
        with pytest.raises(CmdVelRefused, match="must be finite") as refused:
            gate.offer(now, linear, angular, now)
        assert refused.value.kind == "non-finite"
    assert gate.command(now) == twist  # the command before them stays
    with pytest.raises(CmdVelRefused, match=r"past cmd_vel_timeout 0\.5 s") as stale:
        gate.offer(now - 500 * MS, [1.0, 0, 0], [0, 0, 0], now)  # exactly the timeout old: refused
    assert stale.value.kind == "stale" and gate.command(now) == twist
    assert gate.offer(0, [0.3, 0, 0], [0, 0, 0], now) == BaseTwist(0.3)  # a zero stamp is now
    assert gate.command(now + 500 * MS) == BaseTwist(0.3) and not gate.braking
    assert gate.command(now + 501 * MS) == BaseTwist() and gate.braking  # older than the timeout: brake
    forever = CmdVelGate(0.0, holonomic=True)  # 0: no timeout either way
    assert forever.offer(1, [0.1, 0.2, 0.0], [0, 0, 0.3], 10**12) == BaseTwist(0.1, 0.2, 0.3)
    assert forever.command(10**15) == BaseTwist(0.1, 0.2, 0.3)
    with pytest.raises(CmdVelRefused, match=r"linear.x, linear.y, angular.z must be finite"):
        forever.offer(0, [0.1, math.nan, 0.0], [0, 0, 0], 0)  # a holonomic base uses linear.y


def test_targets_are_carried_with_the_base() -> None:
    frame = BaseFrame(BaseOdometry(1.0, 2.0, 0.5, 0.0, 0.0, 0.0))
    # the base moved by (0.5, 0) and turned by 90 deg, moving at (0.1, 0) m/s and turning 0.2 rad/s
    base = BaseOdometry(1.5, 2.0, 0.5 + math.pi / 2, 0.0, 0.0, 0.0)
    position, velocity = frame.carry(base, np.array([0.1, 0.0, 0.2]), np.array([2.0, 2.0, 0.7]), np.zeros(3))
    # the point 1 m ahead along world x of the start base is now 1 m along world y of the moved base
    assert position == pytest.approx([1.5, 3.0, 0.7], abs=1e-15)
    # v_b + omega z x (R (p - p0)) = (0.1, 0) + 0.2 (-1, 0)
    assert velocity == pytest.approx([0.1 - 0.2, 0.0, 0.0], abs=1e-15)
    same, _ = frame.carry(BaseOdometry(1.0, 2.0, 0.5, 0, 0, 0), np.zeros(3), np.array([3.0, -1.0, 0.2]), np.zeros(3))
    assert same == pytest.approx([3.0, -1.0, 0.2], abs=1e-15)  # a base that has not moved carries nothing


def test_wheels_follow_the_inverse_kinematics_and_a_planar_base_its_joints() -> None:
    names = ["base_x", "base_y", "base_yaw", "wheel_left_joint", "wheel_right_joint"]
    wheels = Wheels(("wheel_left_joint",), ("wheel_right_joint",), 0.1, 0.4)
    drive = BaseDrive(names, 0.5, 10.0, wheels)
    assert drive.actuators == [3, 4]
    drive.gate.offer(0, [0.2, 0.0, 0.0], [0.0, 0.0, 1.0], 0)
    q, dq = np.zeros(5), np.array([0.0, 0.0, 0.0, 0.5, 2.5])
    # wanted (0.2 -/+ 0.2) / 0.1 = (0, 4) rad/s
    assert drive.torques(0, q, dq) == pytest.approx([10.0 * (0.0 - 0.5), 10.0 * (4.0 - 2.5)], abs=1e-13)
    planar = BaseDrive(names[:3], 0.5, 10.0)
    assert planar.actuators == [0, 1, 2]
    planar.gate.offer(0, [0.2, 0.1, 0.0], [0.0, 0.0, 0.3], 0)
    tau = planar.torques(0, np.array([0.0, 0.0, math.pi / 2]), np.zeros(3))
    assert tau == pytest.approx([10.0 * -0.1, 10.0 * 0.2, 10.0 * 0.3], abs=1e-13)  # forward is world +y at 90 deg
    with pytest.raises(ValueError, match="no planar base"):
        BaseDrive(["joint1"], 0.5, 10.0)


# -- in process: the controller's policy on the hand-built planar base ---------------------------------------


def stand_in(ctl: dict[str, object] | None = None) -> Scenario:
    return build_scenario(STAND_IN, ctl=ctl)


def test_the_stand_in_lists_its_base_and_odom_s_child_is_the_cart() -> None:
    scenario = stand_in()
    assert list(scenario.plant.joint_names[:3]) == list(BASE_JOINTS)
    assert root_link(scenario.plant.robot.model) == "cart"


def test_cmd_vel_needs_a_planar_base() -> None:
    from conftest import build_scenario as paper

    with pytest.raises(ConfigError, match=r"base_command: cmd_vel drives a mobile base, but \['base_x'"):
        paper(ctl={"base_command": "cmd_vel"})


Drive = tuple[np.ndarray, np.ndarray, np.ndarray, Log]


def drive_in_process(duration_s: float, forward: float, send_until_s: float) -> Drive:
    """The stand-in run by the simulator and the controller's policy (no DDS), cmd_vel ``forward`` [m/s] sent
    every 0.1 s of sim time until ``send_until_s``: per step base_x [m], f_n [N] and the friction force's x
    component on the robot [N]; the policy's log."""
    scenario = stand_in({"base_command": "cmd_vel", "null_space_posture.kd": [0.0] * 7})
    sim = scenario.sim
    log = Log()
    core = StateAnswerer(scenario.controller.config, log, Clock())  # type: ignore[union-attr]
    sent: list[Answer] = []
    steps = round(duration_s / 0.001)
    base_x, normal_force, friction_x = np.zeros(steps), np.zeros(steps), np.zeros(steps)
    for k in range(steps):
        stamp_ns = k * MS
        if k % 100 == 0 and k * 0.001 < send_until_s:
            core.take_cmd_vel(stamp_ns, [forward, 0.0, 0.0], [0.0, 0.0, 0.0])
        core.answer(stamp_ns, sim.position, sim.velocity, lambda _: None, sent.append)
        base_x[k] = sim.position[0]
        d = sim.step(sent[-1].output.command)
        slip = d.slip_velocity[0]
        normal_force[k] = d.normal_force[0]
        friction_x[k] = -d.friction_force[0] * slip[0] / max(np.linalg.norm(slip), 1e-300)
    return base_x, normal_force, friction_x, log


def test_cmd_vel_moves_the_base_while_the_elbow_stays_braced() -> None:
    base_x, f_n, friction_x, log = drive_in_process(2.5, 0.1, 1.0)
    speed = np.diff(base_x) / 0.001
    # cruising, the velocity loop tau = kd (v_cmd - v), kd 100 N s/m, pushes against the braced elbow's Coulomb
    # friction, mu f_n = 1 N against the slip, which is partly along y (the arm sags as the paper's law lets it):
    # the speed lies between 0.1 - mu f_nd / kd = 0.09 m/s (all of it along x) and 0.1 - |f_x| / kd
    cruise = slice(1000, 1399)
    assert 0.09 - 5e-4 < speed[cruise].min()
    assert np.all(speed[cruise] < 0.1 + friction_x[cruise] / 100.0 + 1e-3)
    assert np.all(friction_x[cruise] < -0.7)  # most of it along x, against the motion
    # the last cmd_vel at 0.9 s: 0.5 s later it has timed out and the base brakes to a stop
    assert log.warnings == ["cmd_vel timed out at t = 1.401000 s: braking (zero velocity)"]
    assert abs(speed[-1]) < 1e-3 and base_x[-1] > 0.1
    # the arm takes up what the base's loop would lean on the brace (eq. 40 as the law set it): f_n = f_nd to
    # rounding while the elbow slides, the base speeding up, cruising, braking and at rest; the first step, the
    # elbow breaking free of the floor, is Coulomb friction's, not eq. 40's sliding friction (as test_ur5_scenario)
    assert np.abs(f_n[1:] - 10.0).max() < 1e-9
    assert abs(f_n[0] - 10.0) < 0.3


def test_the_loop_s_integral_is_on_the_commanded_velocity_s_integral() -> None:
    drive = BaseDrive(["base_x", "base_y", "base_yaw"], 0.5, 10.0, ki=100.0)
    drive.gate.offer(0, [0.2, 0.0, 0.0], [0.0, 0.0, 0.0], 0)
    q = np.array([1.0, 2.0, 0.0])
    assert drive.torques(0, q, np.zeros(3)) == pytest.approx([2.0, 0.0, 0.0], abs=1e-15)  # kd 0.2: no error yet
    # 0.1 s later, the base not moved: 2 cm behind where 0.2 m/s puts it
    assert drive.torques(100 * MS, q, np.zeros(3)) == pytest.approx([2.0 + 100.0 * 0.02, 0.0, 0.0], abs=1e-12)
