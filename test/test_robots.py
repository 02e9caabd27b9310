"""Robots beyond the paper's arm: locked joints, prismatic joints through a transmission
radius, task paths (waypoints), the task-rank check and the start check, on the core."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import build_scenario
from test_surfaces import point_robot_urdf

from bracing_core.contacts import ContactSet
from bracing_core.dynamics import ConstrainedDynamics, InputMode
from bracing_core.model import RobotModel
from bracing_core.motors import MotorParams
from bracing_core.params import ConfigError
from bracing_core.simulator import JointLimitError, Simulator
from bracing_core.trajectory import TrajectoryConfig

PAPER_Q0 = np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi


def test_a_locked_joint_is_pinocchios_reduced_model() -> None:
    """Locking the wrist where it starts: three joints move, M is the full M without the locked
    row and column, and the elbow is still on the floor. (Locking the base joint instead leaves
    the elbow one joint: on the floor it cannot move along y, and its brace task is refused.)"""
    locked = {"robot.locked_joints": ["joint4"], "robot.locked_positions": [float(PAPER_Q0[3])]}
    sc = build_scenario(locked, ctl={"hand.axes": ["z"], "hand.kp": [300.0], "hand.kd": [50.0]})  # n - p = 2
    assert sc.plant.joint_names == ("joint1", "joint2", "joint3") and sc.sim.n == 3
    full = build_scenario({}, with_controller=False).plant.robot
    model, data = full.model, full.model.createData()
    mass_full = pin.crba(model, data, PAPER_Q0)
    reduced = sc.plant.robot
    mass_reduced = pin.crba(reduced.model, reduced.model.createData(), PAPER_Q0[:3])
    np.testing.assert_allclose(mass_reduced, mass_full[:3, :3], rtol=1e-12, atol=1e-14)
    sim, ctl = sc.sim, sc.controller
    assert ctl is not None
    for _ in range(200):
        d = sim.step(ctl.update(sim.time, sim.position, sim.velocity).command)
        assert abs(d.residual[0]) < 1e-9
    with pytest.raises(ConfigError, match=r"robot\.locked_joints: 'wrist' is not a joint of"):  # named or not
        build_scenario({"robot.locked_joints": ["wrist"]})
    base = {"robot.locked_joints": ["joint1"], "robot.locked_positions": [float(PAPER_Q0[0])]}
    with pytest.raises(ConfigError, match=r"contacts\.elbow\.brace_axes: frame 'elbow' cannot move along y"):
        build_scenario(base, ctl={"hand.axes": ["z"], "hand.kp": [300.0], "hand.kd": [50.0]})


def test_a_prismatic_joint_is_driven_through_its_transmission_radius(tmp_path: Path) -> None:
    """Reflected constants per SPEC, and the motor's steady speed on a prismatic joint:
    K_m i = (D + D_m) dq and L di = v - R i - K_m dq give dq = K_m v / (R (D + D_m) + K_m^2)."""
    k, rho, torque_constant, resistance, rotor, damping_m = 4.0, 0.05, 0.2, 0.6, 1.6e-4, 0.1
    ones = np.ones(3)
    motors = MotorParams(
        torque_constant * ones,
        resistance * ones,
        0.01 * ones,
        rotor * ones,
        k * ones,
        damping_m * ones,
        transmission_radius=rho * ones,
        thermal=False,  # R fixed: the closed form is the circuit's at R_20 (the winding warms otherwise)
    )
    km = torque_constant * k / rho
    assert motors.reflected_constant == pytest.approx(km * ones)  # [N/A]
    assert motors.reflected_inertia == pytest.approx(rotor * k**2 / rho**2 * ones)  # [kg]
    assert motors.reflected_damping == pytest.approx(damping_m * k**2 / rho**2 * ones)  # [N s/m]
    urdf = tmp_path / "point.urdf"
    urdf.write_text(point_robot_urdf())
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, 0.0))
    assert robot.prismatic.all()
    dynamics = ConstrainedDynamics(robot, motors, ContactSet(robot, []), InputMode.VOLTAGE)
    sim = Simulator(dynamics, 1e-3, np.zeros(3))
    volts = np.array([1.0, 0.0, 0.0])
    for _ in range(3000):
        sim.step(volts)
    total_damping = float(motors.reflected_damping[0])  # the URDF's own damping is 0
    assert sim.velocity[0] == pytest.approx(km * 1.0 / (resistance * total_damping + km**2), rel=1e-6)


def test_a_urdf_limit_stops_the_step_naming_the_joint(tmp_path: Path) -> None:
    urdf = tmp_path / "point.urdf"
    urdf.write_text(point_robot_urdf().replace('lower="-10" upper="10"', 'lower="-0.1" upper="0.1"'))
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, 0.0))
    motors = MotorParams(*(np.ones(3),) * 3, np.zeros(3), np.ones(3), np.zeros(3), transmission_radius=np.ones(3))
    sim = Simulator(ConstrainedDynamics(robot, motors, ContactSet(robot, []), InputMode.TORQUE), 1e-3, np.zeros(3))
    with pytest.raises(JointLimitError, match=r"joint 'x' would leave its URDF limits \[-0\.1, 0\.1\] m"):
        for _ in range(2000):  # 1 N on 1 kg: 0.1 m after ~0.45 s
            sim.step(np.array([1.0, 0.0, 0.0]))
    assert sim.position[0] <= 0.1  # the refused step was not taken
    with pytest.raises(ValueError, match=r"initial_position: joint 'y' at 0\.5 is outside its URDF limits"):
        Simulator(sim.dynamics, 1e-3, np.array([0.0, 0.5, 0.0]))


def test_waypoints_rest_at_each_point_and_are_smooth() -> None:
    waypoints = ((0.1, 0.0, 0.0), (0.1, 0.2, 0.0))
    path = TrajectoryConfig("waypoints", (0.0, 0.0, 0.0), 0.0, 1.0, 1.0, 0.0, (1, 2), None, waypoints, 0.5).build(
        (0, 0, 0)
    )
    for t, point in ((0.0, (0, 0, 0)), (0.5, (0.1, 0, 0)), (1.0, (0.1, 0.2, 0)), (3.0, (0.1, 0.2, 0))):
        position, velocity = path.sample(t)
        assert position == pytest.approx(point, abs=1e-15) and velocity == pytest.approx(np.zeros(3), abs=1e-12)
    position, velocity = path.sample(0.25)  # half way: half the distance, peak speed 15/8 d / T
    assert position == pytest.approx((0.05, 0.0, 0.0)) and velocity[0] == pytest.approx(15 / 8 * 0.1 / 0.5)
    h = 1e-6
    for t in np.linspace(0.01, 0.99, 37):  # the velocity is the position's derivative
        ahead, behind = path.sample(t + h)[0], path.sample(t - h)[0]
        assert (ahead - behind) / (2 * h) == pytest.approx(path.sample(t)[1], abs=1e-6)


def test_a_brace_can_follow_waypoints_while_pushing() -> None:
    """Torque mode: the elbow slides along the floor to a new y and back while the force stays f_nd."""
    y0 = 0.5878
    brace = {
        "input_mode": "torque",
        "contacts.elbow.trajectory.type": "waypoints",
        "contacts.elbow.trajectory.waypoints": [0.0, y0 + 0.05, 0.0, 0.0, y0, 0.0],
        "contacts.elbow.trajectory.segment_time": 1.0,
    }
    sc = build_scenario(brace)
    sim, ctl = sc.sim, sc.controller
    assert ctl is not None
    reached = 0.0
    for _ in range(2000):
        out = ctl.update(sim.time, sim.position, sim.velocity)
        d = sim.step(out.command)
        assert d.normal_force[0] == pytest.approx(10.0, abs=1e-9)
        reached = max(reached, float(out.brace_actual[0][1]))
    assert reached > y0 + 0.03  # it went most of the way


def test_a_direction_the_arm_cannot_move_along_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"hand\.axes: frame 'hand' cannot move along x"):
        build_scenario({}, ctl={"hand.axes": ["x", "y"], "hand.kp": [1.0, 1.0], "hand.kd": [1.0, 1.0]})


def test_the_start_check_names_every_contact_off() -> None:
    two = {
        "contacts.names": ["elbow", "hand"],
        "contacts.hand.frame": "hand",
        "contacts.hand.desired_normal_force": 1.0,
        "contacts.elbow.offset": 0.02,
    }
    with pytest.raises(ConfigError) as info:
        build_scenario(two, with_controller=False)
    message = str(info.value)
    assert "contact 'elbow' (frame 'elbow') is -0.02 m off its plane" in message
    assert "contact 'hand' (frame 'hand') is +0.654" in message


def test_an_in_process_passive_run_summarises_its_obstacle() -> None:
    """--no-bracing in-process (a sweep's row): the elbow is an obstacle the arm rests on."""
    from bracing_core.rollout import run_recorded
    from bracing_experiments.experiment import summarize

    sc = build_scenario({"bracing": False})
    summary = summarize(run_recorded(sc, 0.2), 1.0)
    assert summary["bracing"] is False and summary["input_mode"] == "voltage"
    elbow = summary["contacts"]["elbow"]
    assert elbow["braced"] is False and elbow["normal_force_rms_error_n"] is None
    assert elbow["active_fraction"] == 1.0 and elbow["normal_force_mean_n"] > 0.0  # resting on the floor
    assert summary["max_penetration_m"] < 1e-9
