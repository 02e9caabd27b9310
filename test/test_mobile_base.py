"""Mobile manipulators as real ones ship: continuous joints, a planar base, and the errors that name them.

The engine carries one position per velocity (``bracing_core.base``): a continuous joint as pinocchio's
revolute joint without limits (its unwrapped angle), a planar root as base_x, base_y, base_yaw. These
tests hold that chart to pinocchio's own joints: the same mass matrix and bias forces as the unbounded
revolute joint bit for bit, the same accelerations as the planar joint on its manifold, and the same free
motion as a prismatic-prismatic-revolute stand-in built by hand.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import build_scenario, node_params

from bracing_analysis.series import BagSeries
from bracing_analysis.summary import compute_summary
from bracing_core.base import BaseError, Wheels, chart_urdf
from bracing_core.contacts import ContactSet
from bracing_core.dynamics import ConstrainedDynamics, InputMode
from bracing_core.model import ModelError, RobotModel, simulated_urdf
from bracing_core.motors import MotorParams
from bracing_core.params import ConfigError, resolve_file
from bracing_core.rollout import run_closed_loop, run_recorded
from bracing_core.simulator import Simulator
from bracing_experiments.experiment import summarize

TIAGO = "package://example-robot-data/robots/tiago_description/robots/tiago.urdf"
WHEELS = ["wheel_left_joint", "wheel_right_joint"]
PAPER_URDF = Path(__file__).resolve().parents[1] / "config" / "paper_4link.urdf"


@pytest.fixture(scope="module")
def tiago() -> Path:
    return resolve_file(TIAGO, "robot.urdf")


def _manifold_configuration(charted: pin.Model, native: pin.Model, q: np.ndarray) -> np.ndarray:
    """The configuration of pinocchio's own model (continuous: cos, sin) for the chart's q (same joints)."""
    out = pin.neutral(native)
    for joint in range(1, native.njoints):
        a, b = charted.idx_qs[joint], native.idx_qs[joint]
        if native.nqs[joint] == 2:
            out[b : b + 2] = (math.cos(q[a]), math.sin(q[a]))
        else:
            out[b] = q[a]
    return out


def test_tiago_loads_unmodified_its_wheels_continuous_joints_with_pinocchios_numbers(tiago: Path) -> None:
    """Fails on main (nq=50, nv=48). The chart's M and h + g are the unbounded revolute joints' bit for bit."""
    robot = RobotModel.from_urdf(tiago)
    native = pin.buildModelFromUrdf(str(tiago))
    assert robot.model.nq == robot.nv == native.nv == 48
    assert set(WHEELS) <= set(robot.joint_names)
    wheel = robot.model.getJointId("wheel_left_joint")
    unbounded = np.finfo(float).max  # pinocchio's "no limit"
    assert robot.lower_limits[wheel - 1] == -unbounded and robot.upper_limits[wheel - 1] == unbounded
    rng = np.random.default_rng(46)
    for _ in range(3):
        q = rng.uniform(-1.0, 1.0, robot.nv)
        q[wheel - 1] = 17.3  # unwrapped: several turns
        v, a = rng.uniform(-2.0, 2.0, robot.nv), rng.uniform(-2.0, 2.0, robot.nv)
        q_native = _manifold_configuration(robot.model, native, q)
        assert np.array_equal(pin.crba(robot.model, robot.data, q), pin.crba(native, native.createData(), q_native))
        assert np.array_equal(
            pin.rnea(robot.model, robot.data, q, v, a), pin.rnea(native, native.createData(), q_native, v, a)
        )


def test_tiago_loads_with_its_wheels_locked_where_they_are(tiago: Path) -> None:
    """Fails on main ("'wheel_left_joint' is not a 1-dof joint"). A locked wheel's link sits where the full
    model puts it at that angle, and the published description (the wheel a fixed joint) agrees."""
    at = [0.7, -2.5]
    robot = RobotModel.from_urdf(tiago, locked_joints=WHEELS, locked_positions=at)
    assert robot.nv == 46 and not set(WHEELS) & set(robot.joint_names)
    full = RobotModel.from_urdf(tiago)
    q_full = np.zeros(full.nv)
    for name, angle in zip(WHEELS, at, strict=True):
        q_full[full.model.getJointId(name) - 1] = angle
    full.compute(q_full, np.zeros(full.nv))
    robot.compute(np.zeros(robot.nv), np.zeros(robot.nv))
    shown = RobotModel.from_xml(robot.description())
    shown.compute(np.zeros(shown.nv), np.zeros(shown.nv))
    assert shown.nv == 46
    for link in ("wheel_left_link", "wheel_right_link"):
        expected = full.data.oMf[full.frame_id(link)]
        for model in (robot, shown):
            placed = model.data.oMf[model.frame_id(link)]
            np.testing.assert_allclose(placed.rotation, expected.rotation, atol=1e-12)
            np.testing.assert_allclose(placed.translation, expected.translation, atol=1e-12)


def test_a_continuous_joint_is_driven_past_a_turn_unwrapped(tiago: Path) -> None:
    """A wheel alone (everything else locked), a constant torque, no damping (TIAGo's wheels have none):
    theta = tau t^2 / (2 I) (its centre of mass on its axis: gravity does nothing about it), past 2 pi."""
    text = tiago.read_text()
    others = [j for j in RobotModel.from_urdf(tiago).joint_names if j != "wheel_left_joint"]
    robot = RobotModel.from_urdf(tiago, locked_joints=others)
    assert robot.joint_names == ("wheel_left_joint",) and "continuous" in text
    inertia = float(pin.crba(robot.model, robot.data, np.zeros(1))[0, 0])
    motors = MotorParams(*(np.ones(1),) * 3, np.zeros(1), np.ones(1), np.zeros(1), transmission_radius=np.zeros(1))
    sim = Simulator(ConstrainedDynamics(robot, motors, ContactSet(robot, []), InputMode.TORQUE), 1e-3, np.zeros(1))
    torque, steps = 0.05, 2000
    for _ in range(steps):
        sim.step(np.array([torque]))
    t = steps * 1e-3
    assert sim.position[0] > 2 * math.pi
    assert sim.position[0] == pytest.approx(torque * t**2 / (2 * inertia), rel=1e-12)
    assert sim.velocity[0] == pytest.approx(torque * t / inertia, rel=1e-12)


def test_the_joint_messages_name_the_joints_and_what_to_set(tiago: Path, tmp_path: Path) -> None:
    floating = tmp_path / "floating.urdf"
    floating.write_text(
        tiago.read_text().replace(
            '<link name="base_footprint">',
            '<link name="world"/><joint name="free_root" type="floating"><parent link="world"/>'
            '<child link="base_footprint"/></joint><link name="base_footprint">',
        )
    )
    assert "free_root" in floating.read_text()
    with pytest.raises(ModelError, match=r"joint 'free_root' is floating .*set robot\.base: planar or diff_drive"):
        RobotModel.from_urdf(floating)
    with pytest.raises(ModelError, match=r"robot\.locked_joints: 'no_such_joint' is not a joint of"):
        RobotModel.from_urdf(tiago, locked_joints=["no_such_joint"])
    with pytest.raises(BaseError, match=r"robot\.base: 'holonomic' is not one of fixed, planar, diff_drive"):
        chart_urdf(tiago.read_text(), "holonomic")


def test_a_urdf_without_continuous_joints_or_base_is_read_as_before() -> None:
    text = PAPER_URDF.read_text()
    assert chart_urdf(text) is text
    assert RobotModel.from_urdf(PAPER_URDF).urdf_xml == ""  # the engine reads the file itself, as before
    assert simulated_urdf(text, ["joint4"], [0.3]) == simulated_urdf(text, ["joint4"], [0.3])


# -- the planar base -----------------------------------------------------------------------------------
def _stand_in(text: str) -> str:
    """The paper's arm on a hand-built holonomic base: world -> prismatic x -> prismatic y -> revolute yaw
    -> the arm's root link, the two carriages massless (the stand-in's own small masses set to zero)."""
    root = "base_link" if 'name="base_link"' in text else None
    assert root, "the paper URDF's root link"
    carriages = "".join(f'<link name="{name}"/>' for name in ("world_stand_in", "carriage_x", "carriage_y"))
    joints = ""
    for name, kind, parent, child, axis in (
        ("sx", "prismatic", "world_stand_in", "carriage_x", "1 0 0"),
        ("sy", "prismatic", "carriage_x", "carriage_y", "0 1 0"),
        ("syaw", "revolute", "carriage_y", root, "0 0 1"),
    ):
        joints += (
            f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<axis xyz="{axis}"/><limit lower="-100" upper="100" effort="100" velocity="100"/></joint>'
        )
    return text.replace("</robot>", carriages + joints + "</robot>")


def _free_motion(robot: RobotModel, torque: np.ndarray, q0: np.ndarray, steps: int) -> np.ndarray:
    n = robot.nv
    motors = MotorParams(*(np.ones(n),) * 3, np.zeros(n), np.ones(n), np.zeros(n), transmission_radius=np.zeros(n))
    sim = Simulator(ConstrainedDynamics(robot, motors, ContactSet(robot, []), InputMode.TORQUE), 1e-3, q0)
    path = []
    for _ in range(steps):
        sim.step(torque)
        path.append(np.concatenate([sim.position, sim.velocity]))
    return np.array(path)


def test_a_planar_base_moves_as_a_hand_built_prismatic_prismatic_revolute_stand_in(tmp_path: Path) -> None:
    """robot.base: planar and a URDF planar root joint: the same free motion as the stand-in (its carriages
    massless, the same 5 kg cart under the arm) to 1e-9 (the arm swinging under gravity and the torques
    throw the base about in x, y and yaw), base_x/base_y/base_yaw first."""
    cart = f'<link name="base_link">{_inertial(5.0, 0.1, 0.2, 0.3)}</link>'
    text = PAPER_URDF.read_text().replace('<link name="base_link"/>', cart)  # a 5 kg cart under the arm
    assert cart in text
    arm_on_cart = tmp_path / "arm_on_cart.urdf"
    arm_on_cart.write_text(text)
    stand_in_path = tmp_path / "stand_in.urdf"
    stand_in_path.write_text(_stand_in(text))
    planar_root = tmp_path / "planar_root.urdf"
    planar_root.write_text(
        text.replace(
            "</robot>",
            '<link name="floor"/><joint name="root_planar" type="planar"><parent link="floor"/>'
            '<child link="base_link"/><axis xyz="0 0 1"/></joint></robot>',
        )
    )
    stand_in = RobotModel.from_urdf(stand_in_path)
    assert stand_in.joint_names[:3] == ("sx", "sy", "syaw")
    q0 = np.array([0.1, -0.2, 0.3, *(np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi)])
    torque = np.array([1.0, -2.0, 0.5, 3.0, -1.0, 0.5, 0.2])
    expected = _free_motion(stand_in, torque, q0, 500)
    assert np.ptp(expected[:, 2]) > 0.05 and np.ptp(expected[:, 0]) > 0.02  # the base does move and turn
    for robot in (RobotModel.from_urdf(arm_on_cart, base="planar"), RobotModel.from_urdf(planar_root)):
        assert robot.joint_names[:3] == ("base_x", "base_y", "base_yaw")
        np.testing.assert_allclose(_free_motion(robot, torque, q0, 500), expected, rtol=0.0, atol=1e-9)


def test_the_planar_chart_has_pinocchios_planar_joint_dynamics() -> None:
    """The chart's accelerations are pinocchio's planar joint's (on its manifold, body-frame velocities):
    ddx_world = R(yaw) (dvx - w vy, dvy + w vx) of the body frame's, at random states."""
    robot = RobotModel.from_urdf(PAPER_URDF, base="planar")
    native = pin.buildModelFromUrdf(str(PAPER_URDF), pin.JointModelPlanar())
    native.gravity.linear = robot.gravity
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v, tau = rng.uniform(-1, 1, robot.nv), rng.uniform(-1, 1, robot.nv), rng.uniform(-2, 2, robot.nv)
        yaw, w = q[2], v[2]
        rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        body_velocity = rotation.T @ v[:2]
        q_native = np.concatenate([q[:2], [math.cos(yaw), math.sin(yaw)], q[3:]])
        v_native = np.concatenate([body_velocity, v[2:]])
        tau_native = np.concatenate([rotation.T @ tau[:2], tau[2:]])  # the world force in the body frame
        a = pin.aba(robot.model, robot.data, q, v, tau)
        a_native = pin.aba(native, native.createData(), q_native, v_native, tau_native)
        world = rotation @ (a_native[:2] + w * np.array([-body_velocity[1], body_velocity[0]]))
        np.testing.assert_allclose(a[:2], world, rtol=0, atol=1e-10)
        np.testing.assert_allclose(a[2:], a_native[2:], rtol=0, atol=1e-10)


# -- the differential drive ----------------------------------------------------------------------------
BASE_MASS, BASE_IZZ = 20.0, 0.5  # [kg], [kg m^2] about the axle's midpoint, its centre of mass there
WHEEL_MASS, WHEEL_SPIN, WHEEL_ACROSS = 1.0, 0.005, 0.0025  # [kg], [kg m^2] about its axle, about a diameter
RADIUS, SEPARATION = 0.1, 0.5  # [m]


def _inertial(mass: float, ixx: float, iyy: float, izz: float) -> str:
    return (
        f'<inertial><mass value="{mass!r}"/><inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" '
        f'izz="{izz!r}"/></inertial>'
    )


def diff_drive_urdf(axis_right: str = "0 1 0", axle: str = "y") -> str:
    """A box on two wheels (axle along the base's y, its forward x; or with ``axle`` "x": forward y, the wheels'
    axes -x), the base's centre of mass on the axle's midpoint at wheel height."""
    wheels = ""
    for side, offset in (("left", SEPARATION / 2), ("right", -SEPARATION / 2)):
        axis = "0 1 0" if side == "left" else axis_right
        origin = f"0 {offset!r} 0"
        if axle == "x":
            axis, origin = "-1 0 0", f"{-offset!r} 0 0"
        wheels += (
            f'<link name="wheel_{side}_link">{_inertial(WHEEL_MASS, WHEEL_ACROSS, WHEEL_SPIN, WHEEL_ACROSS)}</link>'
            f'<joint name="wheel_{side}_joint" type="continuous"><parent link="base_link"/>'
            f'<child link="wheel_{side}_link"/><origin xyz="{origin}"/><axis xyz="{axis}"/></joint>'
        )
    return (
        '<?xml version="1.0"?><robot name="cart"><link name="base_footprint"/>'
        f'<link name="base_link">{_inertial(BASE_MASS, 0.3, 0.3, BASE_IZZ)}</link>'
        '<joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>'
        f'<origin xyz="0 0 {RADIUS!r}"/></joint>{wheels}</robot>'
    )


def _cart(tmp_path: Path, axis_right: str = "0 1 0") -> RobotModel:
    urdf = tmp_path / "cart.urdf"
    urdf.write_text(diff_drive_urdf(axis_right))
    return RobotModel.from_urdf(
        urdf, base="diff_drive", wheels=Wheels(("wheel_left_joint",), ("wheel_right_joint",), RADIUS, SEPARATION)
    )


def _roll(robot: RobotModel, left: float, right: float, steps: int) -> tuple[np.ndarray, float]:
    """Wheel torques held from rest (torque input, no damping): the base's (x, y, yaw) per step and the
    largest rolling residual |A v| [m/s]."""
    n = robot.nv
    motors = MotorParams(*(np.ones(n),) * 3, np.zeros(n), np.ones(n), np.zeros(n), transmission_radius=np.zeros(n))
    dynamics = ConstrainedDynamics(robot, motors, ContactSet(robot, []), InputMode.TORQUE)
    sim = Simulator(dynamics, 1e-3, np.zeros(n))
    torque = np.zeros(n)
    torque[robot.joint_names.index("wheel_left_joint")] = left
    torque[robot.joint_names.index("wheel_right_joint")] = right
    poses, residual = [], 0.0
    for _ in range(steps):
        answer = sim.step(torque)
        residual = max(residual, float(np.max(np.abs(answer.rolling_velocity))))
        poses.append(sim.position[:3].copy())
    return np.array(poses), residual


def test_a_diff_drive_goes_straight_on_equal_torques_and_turns_on_the_unicycles_radius(tmp_path: Path) -> None:
    """Fails on main (no robot.base). From rest under constant wheel torques, with the base's centre of mass on
    the axle's midpoint, the forward and yaw motions decouple: m a = (tau_l + tau_r) / r and
    I alpha = (b / 2)(tau_r - tau_l) / r, m and I with the wheels' spin inertia reflected (I_w / r^2, and
    I_w (b / 2)^2 / r^2), so v / w = a / alpha is constant: a circle of radius R = a / alpha through the start,
    centred at (0, R). Equal torques: a straight line, x = a t^2 / 2. Rolling residual <= 1e-9 m/s."""
    robot = _cart(tmp_path)
    assert robot.joint_names == ("base_x", "base_y", "base_yaw", "wheel_left_joint", "wheel_right_joint")
    mass = BASE_MASS + 2 * WHEEL_MASS + 2 * WHEEL_SPIN / RADIUS**2
    inertia = (
        BASE_IZZ
        + 2 * (WHEEL_ACROSS + WHEEL_MASS * (SEPARATION / 2) ** 2)
        + 2 * WHEEL_SPIN * (SEPARATION / 2) ** 2 / RADIUS**2
    )
    straight, residual = _roll(robot, 0.4, 0.4, 1000)
    assert residual <= 1e-9
    t = 1.0
    assert straight[-1, 0] == pytest.approx((0.8 / RADIUS / mass) * t**2 / 2, rel=1e-9)
    assert np.max(np.abs(straight[:, 1:])) <= 1e-12
    left, right = 0.3, 0.5
    turning, residual = _roll(robot, left, right, 2000)
    assert residual <= 1e-9
    acceleration = (left + right) / RADIUS / mass
    angular = (SEPARATION / 2) * (right - left) / RADIUS / inertia
    radius = acceleration / angular  # [m]
    assert turning[-1, 2] == pytest.approx(angular * 2.0**2 / 2, rel=1e-9) and turning[-1, 2] > 1.0  # it turns
    distance = np.hypot(turning[:, 0], turning[:, 1] - radius)
    np.testing.assert_allclose(distance, radius, rtol=0, atol=1e-9)


def test_a_wheel_axis_turned_over_rolls_the_same(tmp_path: Path) -> None:
    """The right wheel's axis along -y (as many URDFs mount it): the same motion with its torque negated."""
    flipped, residual = _roll(_cart(tmp_path, "0 -1 0"), 0.3, -0.5, 500)
    assert residual <= 1e-9
    expected, _ = _roll(_cart(tmp_path), 0.3, 0.5, 500)
    np.testing.assert_allclose(flipped, expected, rtol=0, atol=1e-12)


# -- bad input, before the run starts -------------------------------------------------------------------
def _cart_scenario(tmp_path: Path, urdf_text: str, joints: list[str], **robot: object) -> None:
    """The cart's simulator plant from the paper's file, robot.* overridden (raises what the nodes raise)."""
    urdf = tmp_path / "cart_case.urdf"
    urdf.write_text(urdf_text)
    n = len(joints)
    motors = {f"motors.{field}": [1.0] * n for field in ("torque_constant", "resistance", "inductance", "gear_ratio")}
    motors |= {f"motors.{f}": [0.0] * n for f in ("rotor_inertia", "gear_damping", "transmission_radius")}
    motors |= {f"motors.{f}": [1.0] * n for f in ("thermal_resistance", "heat_capacity")}
    shared = {
        "robot.urdf": str(urdf),
        "robot.joint_names": joints,
        "contacts.names": [],
        **motors,
        **{f"robot.{key}": value for key, value in robot.items()},
    }
    build_scenario(shared, sim={"initial_position": [0.0] * n, "initial_velocity": [0.0] * n}, with_controller=False)


DIFF_DRIVE = {
    "base": "diff_drive",
    "left_wheel_names": ["wheel_left_joint"],
    "right_wheel_names": ["wheel_right_joint"],
    "wheel_radius": RADIUS,
    "wheel_separation": SEPARATION,
}


def test_bad_wheels_are_named_before_the_run_starts(tmp_path: Path) -> None:
    """Fails on main (robot.base unknown). Each error names what is wrong and what to set."""
    cart, wheels = diff_drive_urdf(), ["wheel_left_joint", "wheel_right_joint"]
    with pytest.raises(ConfigError, match=r"'base_joint' is a fixed joint of .*a wheel turns on a continuous or"):
        _cart_scenario(tmp_path, cart, wheels, **(DIFF_DRIVE | {"left_wheel_names": ["base_joint"]}))
    with pytest.raises(ConfigError, match=r"'tyre' is not a joint of"):
        _cart_scenario(tmp_path, cart, wheels, **(DIFF_DRIVE | {"right_wheel_names": ["tyre"]}))
    for key in ("wheel_radius", "wheel_separation"):
        for bad in (0.0, -0.1):
            with pytest.raises(ConfigError, match=rf"robot\.{key}: .*> 0"):
                _cart_scenario(tmp_path, cart, wheels, **(DIFF_DRIVE | {key: bad}))
    with pytest.raises(ConfigError, match=r"robot\.wheel_radius: .*required|robot\.wheel_radius"):
        _cart_scenario(tmp_path, cart, wheels, **{k: v for k, v in DIFF_DRIVE.items() if k != "wheel_radius"})
    with pytest.raises(ConfigError, match=r"robot\.joint_names omits the wheel 'wheel_right_joint'.*robot\.locked_"):
        _cart_scenario(tmp_path, cart, ["wheel_left_joint"], **DIFF_DRIVE)
    with pytest.raises(ConfigError, match=r"locks one wheel of the differential drive: lock both .* or neither"):
        _cart_scenario(tmp_path, cart, wheels, **(DIFF_DRIVE | {"locked_joints": ["wheel_left_joint"]}))
    with pytest.raises(ConfigError, match=r"robot\.wheel_separation: 0\.45 m, but the URDF's wheels are 0\.5 m apart"):
        _cart_scenario(tmp_path, cart, wheels, **(DIFF_DRIVE | {"wheel_separation": 0.45}))
    with pytest.raises(ConfigError, match=r"not on their common axis"):
        _cart_scenario(tmp_path, cart.replace('xyz="0 0.25 0"', 'xyz="0.1 0.25 0"'), wheels, **DIFF_DRIVE)
    with pytest.raises(ConfigError, match=r"turning wheels takes input_mode: torque .*or lock both wheels"):
        _cart_scenario(tmp_path, cart, wheels, **DIFF_DRIVE)
    floating = cart.replace(
        '<link name="base_footprint"/>',
        '<link name="floor"/><joint name="slide" type="planar"><parent link="floor"/><child link="base_footprint"/>'
        '</joint><link name="base_footprint"/>',
    )
    with pytest.raises(ConfigError, match=r"diff_drive adds the planar root .* already floats \(planar joint 'slide'"):
        _cart_scenario(tmp_path, floating, wheels, **DIFF_DRIVE)


def arm_on_cart_urdf(axle: str = "y") -> str:
    """The paper's arm on the cart: its base_link is the cart's (massive, on the axle 0.1 m up), its joint1 there."""
    cart = diff_drive_urdf(axle=axle)
    body = cart[cart.index('<link name="base_footprint"/>') : cart.index("</robot>")]
    return PAPER_URDF.read_text().replace('<link name="base_link"/>', body)


def test_a_braked_diff_drive_base_holds_the_arm_braced_at_the_desired_force(tmp_path: Path) -> None:
    """Fails on main (robot.base unknown). Both wheels locked: on wheels that cannot turn and cannot slip the
    base cannot move, so base_x, base_y and base_yaw leave the model with them (held at 0, the odom origin),
    and the paper's torque law holds its elbow on a table at the axle's height at f_n = f_nd to 1e-9 N."""
    urdf = tmp_path / "arm_on_cart.urdf"
    urdf.write_text(arm_on_cart_urdf())
    shared = {
        "robot.urdf": str(urdf),
        "input_mode": "torque",
        "robot.locked_joints": ["wheel_left_joint", "wheel_right_joint"],
        "contacts.elbow.offset": RADIUS,  # the table top: the elbow starts on it, 0.1 m up with the arm
        **{f"robot.{key}": value for key, value in DIFF_DRIVE.items()},
    }
    scenario = build_scenario(shared)
    assert scenario.plant.joint_names == ("joint1", "joint2", "joint3", "joint4")
    run = run_closed_loop(scenario, 1.0)
    assert np.max(np.abs(run.normal_force[:, 0] - 10.0)) <= 1e-9
    assert np.max(np.abs(run.residual)) <= 1e-9


def test_the_paper_arm_on_a_planar_base_braces_at_the_desired_force_while_its_base_moves() -> None:
    """Fails on main (robot.base unknown). robot.base: planar: base_x, base_y, base_yaw are joints like the arm's,
    listed, each with a motor (base_x and base_y through a 5 cm wheel), and the paper's torque law runs on all
    seven: the elbow's force is f_nd to 1e-9 N every step while the hand's task moves the base."""
    joints = ["base_x", "base_y", "base_yaw", "joint1", "joint2", "joint3", "joint4"]
    paper = node_params("bracing_simulator")  # the paper's motor on every joint
    motors = {
        k: [v[0]] * 7 for k, v in paper.items() if k.startswith("motors.") and isinstance(v, list) and len(v) == 4
    }
    motors["motors.transmission_radius"] = [0.05, 0.05, 0.0, 0.0, 0.0, 0.0, 0.0]
    shared = {"robot.base": "planar", "robot.joint_names": joints, "input_mode": "torque", **motors}
    q0 = [0.0, 0.0, 0.0, *(np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi)]
    ctl = {"voltage_gain": [1.0] * 7, "null_space_posture.kp": [0.0] * 7, "null_space_posture.kd": [0.0] * 7}
    scenario = build_scenario(shared, sim={"initial_position": q0, "initial_velocity": [0.0] * 7}, ctl=ctl)
    assert scenario.plant.joint_names == tuple(joints)
    run = run_closed_loop(scenario, 1.0)
    assert np.max(np.abs(run.normal_force[:, 0] - 10.0)) <= 1e-9
    assert np.ptp(run.position[:, 0]) + np.ptp(run.position[:, 1]) > 1e-4  # the base takes part


def test_the_summary_has_the_bases_travel_and_rolling_residual() -> None:
    """Fails on main (no such keys). base_travel_m: the (base_x, base_y) path's length, 3-4-5 legs by hand;
    null without a moving base; base_rolling_residual_max_m_s: the largest recorded |A v|, null unrecorded."""
    path = np.array([[0.0, 0.0, 0.5], [3.0, 4.0, 0.1], [3.0, 0.0, 0.2], [3.0, 0.0, 0.3]])
    series = BagSeries(joint_t=np.arange(4.0), joint_names=["base_x", "base_y", "joint1"], joint_position=path)
    series.base_rolling_residual = np.array([1e-12, 3e-11, 2e-12])
    summary = compute_summary(series)
    assert summary["base_travel_m"] == pytest.approx(9.0, abs=1e-15)
    assert summary["base_rolling_residual_max_m_s"] == 3e-11
    fixed = compute_summary(BagSeries(joint_t=np.arange(4.0), joint_names=["joint1"], joint_position=path[:, 2:]))
    assert fixed["base_travel_m"] is None and fixed["base_rolling_residual_max_m_s"] is None


def test_the_torque_law_on_the_rolling_arm_holds_the_brace_and_the_hand_while_the_wheels_drive_the_base(
    tmp_path: Path,
) -> None:
    """Fails on main (robot.base unknown). The paper arm on the cart with its wheels turning (torque input): the
    base has no motor, the law runs on the admissible motions (the base's velocities those the wheels' rolling
    gives, docs/model.md), so the brace holds f_n = f_nd to 1e-9 N every step, the base's torque is zero, the
    wheels roll without slipping (residual <= 1e-9 m/s) and the hand's task moves the base on its wheels."""
    urdf = tmp_path / "arm_on_cart.urdf"
    urdf.write_text(arm_on_cart_urdf(axle="x"))  # the cart rolls along y, in the arm's plane
    joints = ["wheel_left_joint", "wheel_right_joint", "joint1", "joint2", "joint3", "joint4"]
    paper = node_params("bracing_simulator")
    motors = {
        k: [v[0]] * 6 for k, v in paper.items() if k.startswith("motors.") and isinstance(v, list) and len(v) == 4
    }
    shared = {
        "robot.urdf": str(urdf),
        "robot.joint_names": joints,
        "input_mode": "torque",
        "contacts.elbow.offset": RADIUS,
        **motors,
        **{f"robot.{key}": value for key, value in DIFF_DRIVE.items()},
    }
    q0 = [0.0, 0.0, *(np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi)]
    sim = {"initial_position": q0, "initial_velocity": [0.0] * 6}
    ctl = {"voltage_gain": [1.0] * 6, "null_space_posture.kp": [0.0] * 6, "null_space_posture.kd": [0.0] * 6}
    scenario = build_scenario(shared, sim=sim, ctl=ctl)
    names = scenario.plant.joint_names
    assert names[:3] == ("base_x", "base_y", "base_yaw") and scenario.plant.robot.wheels is not None
    run = run_closed_loop(scenario, 1.0)
    assert np.max(np.abs(run.normal_force[:, 0] - 10.0)) <= 1e-9
    assert np.max(np.abs(run.command[:, :3])) == 0.0  # no base motor
    assert np.max(np.abs(run.residual)) <= 1e-9
    base = run.position[:, :3]
    assert np.ptp(base[:, 0]) + np.ptp(base[:, 1]) > 1e-4  # the wheels move the base
    # no slip: the base's velocity has no part along its axle (its x); the forward speed (along its y) is
    # r (wl + wr) / 2 and the yaw rate r (wr - wl) / b: the unicycle's kinematics
    yaw, velocity = run.position[:, 2], run.velocity
    lateral = np.cos(yaw) * velocity[:, 0] + np.sin(yaw) * velocity[:, 1]
    forward = -np.sin(yaw) * velocity[:, 0] + np.cos(yaw) * velocity[:, 1]
    wheels = velocity[:, [names.index("wheel_left_joint"), names.index("wheel_right_joint")]]
    assert np.max(np.abs(lateral)) <= 1e-9
    np.testing.assert_allclose(forward, RADIUS * wheels.mean(axis=1), rtol=0, atol=1e-9)
    np.testing.assert_allclose(velocity[:, 2], RADIUS * (wheels[:, 1] - wheels[:, 0]) / SEPARATION, rtol=0, atol=1e-9)
    assert run.hand_error[-1] < run.hand_error[0]  # the hand closes on its path
    summary = summarize(run_recorded(build_scenario(shared, sim=sim, ctl=ctl), 1.0), wall_time_s=1.0)
    assert 0.05 < summary["base_travel_m"] < 0.2 and summary["base_rolling_residual_max_m_s"] <= 1e-9
