"""Curved surfaces against hand-checked geometry: a point mass sliding on a sphere and on a
cylinder, where the constraint force is the centripetal force and nothing else.

The robot is a Cartesian point: three prismatic joints (x, y, z) carrying a 1 kg tip on links
of 1e-9 kg, so that M = 1 kg I to 1e-9. With no gravity, no damping, no friction and no
input, a point held on a sphere of radius R moving at speed v must keep |v| and feel
f_n = -m v^2 / R along the outward normal (the surface pulls it towards the centre); on a
cylinder, moving around the axis the same, along the axis nothing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bracing_core.config import SimulatorConfig, build_simulator
from bracing_core.contacts import Contact, ContactSet, Cylinder, Plane, Sphere
from bracing_core.dynamics import ConstrainedDynamics, InputMode
from bracing_core.model import RobotModel
from bracing_core.motors import MotorParams
from bracing_core.params import ConfigError
from bracing_core.simulator import Simulator

MASS = 1.0  # [kg], the tip
LIGHT = 1e-9  # [kg], the carriages


def point_robot_urdf() -> str:
    links, joints = ['<link name="world_base"/>'], []
    parent = "world_base"
    for axis, name in (("1 0 0", "x"), ("0 1 0", "y"), ("0 0 1", "z")):
        mass = MASS if name == "z" else LIGHT
        links.append(
            f'<link name="carriage_{name}"><inertial><mass value="{mass!r}"/>'
            '<inertia ixx="1e-12" ixy="0" ixz="0" iyy="1e-12" iyz="0" izz="1e-12"/></inertial></link>'
        )
        joints.append(
            f'<joint name="{name}" type="prismatic"><parent link="{parent}"/><child link="carriage_{name}"/>'
            f'<axis xyz="{axis}"/><limit lower="-10" upper="10" effort="1000" velocity="100"/>'
            '<dynamics damping="0.0"/></joint>'
        )
        parent = f"carriage_{name}"
    joints.append('<joint name="tip_joint" type="fixed"><parent link="carriage_z"/><child link="tip"/></joint>')
    links.append('<link name="tip"/>')
    return '<?xml version="1.0"?><robot name="point">' + "".join(links + joints) + "</robot>"


@pytest.fixture(scope="module")
def urdf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("point") / "point.urdf"
    path.write_text(point_robot_urdf())
    return path


def motors(n: int = 3) -> MotorParams:
    ones = np.ones(n)
    return MotorParams(ones, ones, ones, 0 * ones, ones, 0 * ones, transmission_radius=0.01 * ones)


def simulator(urdf: Path, surface: Sphere | Cylinder | Plane, q0: np.ndarray, dq0: np.ndarray) -> Simulator:
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, 0.0))
    contacts = ContactSet(robot, [Contact("touch", "tip", surface)])
    dynamics = ConstrainedDynamics(robot, motors(), contacts, InputMode.TORQUE)
    return Simulator(dynamics, 1e-3, q0, dq0)


def test_point_on_a_sphere_feels_the_centripetal_force(urdf: Path) -> None:
    radius, speed = 0.5, 0.8
    center = np.array([0.1, -0.2, 0.3])
    q0 = center + np.array([0.0, 0.0, radius])  # on top
    sim = simulator(urdf, Sphere(center, radius), q0, np.array([speed, 0.0, 0.0]))
    expected = -MASS * speed**2 / radius
    for _ in range(1000):  # 1 s: a third of a great circle
        d = sim.step(np.zeros(3))
        assert d.normal_force[0] == pytest.approx(expected, rel=1e-6)
        assert abs(d.residual[0]) < 1e-9  # the curvature term of gamma keeps it on the sphere
    position = sim.position
    assert np.linalg.norm(position - center) == pytest.approx(radius, abs=1e-9)
    assert np.linalg.norm(sim.velocity) == pytest.approx(speed, rel=1e-9)  # no work done by the constraint
    angle = np.arccos(np.clip((position - center)[2] / radius, -1.0, 1.0))
    assert angle == pytest.approx(speed * 1.0 / radius, rel=1e-6)  # travelled v t along the great circle


def test_inside_a_sphere_the_force_points_inwards_and_pushes(urdf: Path) -> None:
    radius, speed = 0.5, 0.8
    center = np.zeros(3)
    sim = simulator(urdf, Sphere(center, radius, inside=True), np.array([0.0, 0.0, -radius]), np.array([speed, 0, 0]))
    d = sim.step(np.zeros(3))
    # Inside, n points to the centre and the wall pushes the point along it: +m v^2 / R.
    assert d.normals[0] == pytest.approx([0.0, 0.0, 1.0])
    assert d.normal_force[0] == pytest.approx(MASS * speed**2 / radius, rel=1e-6)


def test_point_on_a_cylinder_around_and_along_the_axis(urdf: Path) -> None:
    radius, speed = 0.3, 0.6
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    point = np.array([0.0, 0.0, 0.2])
    start = point + np.array([0.0, 0.0, radius])  # on top of a horizontal pipe
    around = np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0) * speed
    sim = simulator(urdf, Cylinder(point, axis, radius), start, around)
    for _ in range(500):
        d = sim.step(np.zeros(3))
        assert d.normal_force[0] == pytest.approx(-MASS * speed**2 / radius, rel=1e-6)
        assert abs(d.residual[0]) < 1e-9
    along = simulator(urdf, Cylinder(point, axis, radius), start, axis * speed)
    for _ in range(200):
        d = along.step(np.zeros(3))
        assert abs(d.normal_force[0]) < 1e-9  # a straight line on the surface: no force needed


def test_friction_acts_in_the_tangent_plane_against_the_slip(urdf: Path) -> None:
    """Pressed on a sphere by gravity at its top and sliding, friction mu f_n slows the point
    along its slip direction, in the tangent plane."""
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, -9.81))
    center, radius, mu = np.zeros(3), 0.5, 0.2
    contacts = ContactSet(robot, [Contact("touch", "tip", Sphere(center, radius), friction=mu)], slip_epsilon=1e-6)
    sim = Simulator(
        ConstrainedDynamics(robot, motors(), contacts, InputMode.TORQUE),
        1e-3,
        np.array([0.0, 0.0, radius]),
        np.array([0.5, 0.0, 0.0]),
    )
    d = sim.evaluate(np.zeros(3))
    # At the top: f_n = m g - m v^2 / R; friction mu f_n against +x; the point decelerates at mu f_n / m.
    normal_force = MASS * 9.81 - MASS * 0.25 / radius
    assert d.normal_force[0] == pytest.approx(normal_force, rel=1e-6)
    assert d.slip_direction[0] == pytest.approx([1.0, 0.0, 0.0], abs=1e-5)
    assert d.acceleration[0] == pytest.approx(-mu * normal_force / MASS, rel=1e-5)
    assert d.acceleration[2] == pytest.approx(-0.25 / radius, rel=1e-5)  # centripetal, towards the centre


def test_yaml_surfaces_reach_the_simulator(urdf: Path) -> None:
    """contacts.<name>.surface: sphere / cylinder from parameters, and their errors named."""
    base = {
        "robot.urdf": str(urdf),
        "robot.joint_names": ["x", "y", "z"],
        "robot.gravity": [0.0, 0.0, 0.0],
        "input_mode": "torque",
        **{f"motors.{k}": [1.0, 1.0, 1.0] for k in ("torque_constant", "resistance", "inductance", "gear_ratio")},
        "motors.rotor_inertia": [0.0, 0.0, 0.0],
        "motors.gear_damping": [0.0, 0.0, 0.0],
        "motors.transmission_radius": [0.01, 0.01, 0.01],
        "contacts.names": ["ball"],
        "contacts.ball.frame": "tip",
        "contacts.ball.surface": "sphere",
        "contacts.ball.center": [0.0, 0.0, 0.0],
        "contacts.ball.radius": 0.4,
        "contacts.ball.desired_normal_force": 1.0,  # braced, so bilateral: the projection holds it
        "initial_position": [0.0, 0.3, 0.2],  # 0.36 m from the centre: a guess
        "project_initial_position": True,
    }
    _, sim = build_simulator(SimulatorConfig.from_params(base))
    assert np.linalg.norm(sim.position) == pytest.approx(0.4, abs=1e-12)  # projected onto the sphere
    obstacle = {k: v for k, v in base.items() if k != "contacts.ball.desired_normal_force"}
    off = r"infeasible start: contact 'ball' \(frame 'tip'\) is -0.0394\d* m off its sphere"
    with pytest.raises(ConfigError, match=off):
        build_simulator(SimulatorConfig.from_params(obstacle))  # an obstacle is not projected: inside it
    with pytest.raises(ConfigError, match=r"contacts\.ball\.radius: a sphere needs a radius > 0"):
        SimulatorConfig.from_params({**base, "contacts.ball.radius": 0.0})
    with pytest.raises(ConfigError, match=r"contacts\.ball\.center"):
        SimulatorConfig.from_params({k: v for k, v in base.items() if k != "contacts.ball.center"})
    with pytest.raises(ConfigError, match=r"motors\.transmission_radius: joint 'y' is prismatic"):
        build_simulator(SimulatorConfig.from_params({**base, "motors.transmission_radius": [0.01, 0.0, 0.01]}))
