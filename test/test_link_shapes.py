"""The links' collision shapes: the generated arms carry one per link, the shape drawn, with nothing else
changed; MuJoCo keeps them with robot.collision_geometry and rests a dropped link on its shape.

The pendulum: one cylinder link (m = 1 kg, L = 0.5 m, r = 0.03 m) on a joint about x 0.3 m above the floor
z = 0, let go horizontal. Resting on its shape, the lowest point of its tip's rim is on the floor:
0.3 - L sin(theta) - r cos(theta) = 0 (theta below the horizontal), theta_shape = 0.5825 rad; a frame at the
tip (or MuJoCo's 5 mm contact sphere centred on it) rests where 0.3 - L sin(theta) = 0, theta_frame = 0.6435.
Tolerance: MuJoCo's contacts are soft (default solref 0.02 s, solimp 0.9-0.95): the rim rests slightly
inside the floor; the test asks at most 1 mm (the issue's figure), which moves theta by at most
1 mm / (L cos(theta) - r sin(theta)) = 2.5 mrad: theta within 3 mrad of theta_shape, 60 mrad from theta_frame.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from bracing_core import chain_urdf
from bracing_core.chain_urdf import JointSpec, LinkSpec, serial_chain_urdf
from bracing_core.rollout import build_scenario
from bracing_mujoco.mujoco_plant import SHAPE_BIT, MujocoRobot, bare_urdf

CONFIG = Path(__file__).resolve().parent.parent / "config"
GENERATED = sorted({name for name, make in chain_urdf.SCENARIOS.items() if make.__name__ == f"{name}_urdf"})

PIVOT_Z, LENGTH, RADIUS, MASS = 0.3, 0.5, 0.03, 1.0
# L sin(theta) + r cos(theta) = sqrt(L^2 + r^2) sin(theta + atan2(r, L)) = PIVOT_Z
THETA_SHAPE = math.asin(PIVOT_Z / math.hypot(LENGTH, RADIUS)) - math.atan2(RADIUS, LENGTH)
THETA_FRAME = math.asin(PIVOT_Z / LENGTH)
REST_TOLERANCE_RAD = 3e-3
SCENARIO = """/**:
  ros__parameters:
    robot:
      urdf: pendulum.urdf
      joint_names: [joint1]
      collision_geometry: {geometry}
      collision_links: {links}
    input_mode: torque
    motors:
      torque_constant: [0.2]
      resistance: [0.6]
      inductance: [0.17]
      rotor_inertia: [0.000164]
      gear_ratio: [3.0]
      gear_damping: [0.1]
      transmission_radius: [0.0]
    contacts:
      names: [floor]
      floor:
        frame: tip
        normal: [0.0, 0.0, 1.0]
        friction: 0.5
bracing_simulator:
  ros__parameters:
    initial_position: [{start}]
    initial_velocity: [0.0]
    duration: 3.0
"""


def moving_links(urdf: str) -> list[str]:
    return [str(link.get("name")) for link in ET.fromstring(urdf).iter("link") if link.find("inertial") is not None]


def _strip_collision(text: str) -> str:
    return re.sub(r"\s*<collision>.*?</collision>", "", text, flags=re.DOTALL)


# --------------------------------------------------------------------------- the generated URDFs


@pytest.mark.parametrize("name", GENERATED)
def test_every_generated_link_collides_with_the_shape_it_is_drawn_with(name: str) -> None:
    """pinocchio's COLLISION model of each generated arm has one shape per moving link, the VISUAL one
    (type, size, placement), and config/NAME.urdf is the generator's output."""
    text = chain_urdf.SCENARIOS[name]()
    assert (CONFIG / f"{name}.urdf").read_text() == text
    model = pin.buildModelFromXML(text)
    visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    collision = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    assert [g.name.rsplit("_", 1)[0] for g in collision.geometryObjects] == moving_links(text)
    for shown, shape in zip(visual.geometryObjects, collision.geometryObjects, strict=True):
        assert type(shape.geometry) is type(shown.geometry)
        assert shape.placement.isApprox(shown.placement, 0.0)
        assert shape.parentJoint == shown.parentJoint
        for size in ("radius", "halfLength", "halfSide"):
            if hasattr(shown.geometry, size):
                assert np.array_equal(getattr(shape.geometry, size), getattr(shown.geometry, size))


@pytest.mark.parametrize("name", GENERATED)
def test_collision_shapes_change_no_inertia_and_no_mujoco_model_with_the_knob_off(name: str) -> None:
    """Bit for bit: pinocchio's inertias, and MuJoCo's import of the URDF (knob off), with the shapes as
    without them; with the knob on MuJoCo has a geom per link and the same masses."""
    text = chain_urdf.SCENARIOS[name]()
    bare = _strip_collision(text)
    assert bare != text and "<collision>" not in bare
    with_shapes, without = pin.buildModelFromXML(text), pin.buildModelFromXML(bare)
    for a, b in zip(with_shapes.inertias, without.inertias, strict=True):
        assert np.array_equal(a.toDynamicParameters(), b.toDynamicParameters())

    saved = []
    for urdf in (text, bare):  # as the MuJoCo path imports a URDF with robot.collision_geometry off
        model = mujoco.MjSpec.from_string(bare_urdf(urdf)).compile()
        buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
        mujoco.mj_saveModel(model, None, buffer)
        saved.append(buffer.tobytes())
    kept = mujoco.MjSpec.from_string(bare_urdf(text, keep_collision=True)).compile()
    assert kept.ngeom == len(moving_links(text)) and np.array_equal(kept.body_mass, model.body_mass)
    assert saved[0] == saved[1]


# --------------------------------------------------------------------------- MuJoCo rests a link on its shape


def _pendulum(tmp_path: Path, geometry: bool, links: list[str]) -> Path:
    joint = JointSpec("joint1", axis=(1.0, 0.0, 0.0), offset=PIVOT_Z, damping=0.5)
    link = LinkSpec("link1", MASS, LENGTH, RADIUS)
    (tmp_path / "pendulum.urdf").write_text(serial_chain_urdf("pendulum", [joint], [link], {"tip": 1}))
    path = tmp_path / "pendulum.yaml"
    # Horizontal at the start, along +y: the link falls towards -z, its angle below the horizontal theta
    # where q = -(pi/2 + theta).
    start = repr(-math.pi / 2)
    path.write_text(SCENARIO.format(geometry=str(geometry).lower(), links=links, start=start))
    return path


def _rest(robot: MujocoRobot, seconds: float = 3.0) -> tuple[float, float]:
    """Let the link fall and settle: (theta [rad] below the horizontal, |dq| [rad/s]) at the end."""
    for _ in range(round(seconds / robot.model.opt.timestep)):
        robot.step(np.zeros(1))
    q, dq = robot.state()
    return -float(q[0]) - math.pi / 2, abs(float(dq[0]))


def _lowest_rim_z(theta: float) -> float:
    return PIVOT_Z - LENGTH * math.sin(theta) - RADIUS * math.cos(theta)


def test_mujoco_rests_a_dropped_collision_link_on_its_shape(tmp_path: Path) -> None:
    scenario = build_scenario(_pendulum(tmp_path, True, ["link1"]), with_controller=False)
    robot = MujocoRobot.build(scenario.sim_config)
    shapes = [g for g in range(robot.model.ngeom) if robot.model.geom_contype[g] & SHAPE_BIT]
    assert [robot.model.body(robot.model.geom_bodyid[g]).name for g in shapes] == ["link1"]
    assert robot.model.geom_type[shapes[0]] == mujoco.mjtGeom.mjGEOM_CYLINDER
    theta, speed = _rest(robot)
    rim = _lowest_rim_z(theta)
    print(f"\nrest {theta:.5f} rad (shape {THETA_SHAPE:.5f}, frame {THETA_FRAME:.5f}); rim z {rim:.2e} m")
    assert speed < 1e-3
    assert -1e-3 <= rim <= 1e-4  # on the floor: at most 1 mm in (soft contact), not above it
    assert theta == pytest.approx(THETA_SHAPE, abs=REST_TOLERANCE_RAD)


def test_without_the_knob_mujoco_collides_the_tip_sphere_only(tmp_path: Path) -> None:
    """Today's MuJoCo path: the shapes dropped, the link passes into the floor until the 5 mm sphere at the
    tip frame rests on the floor moved out by its radius, i.e. the tip frame on the floor."""
    scenario = build_scenario(_pendulum(tmp_path, False, []), with_controller=False)
    robot = MujocoRobot.build(scenario.sim_config)
    assert not any(robot.model.geom_contype & SHAPE_BIT)
    theta, speed = _rest(robot)
    assert speed < 1e-3
    assert theta == pytest.approx(THETA_FRAME, abs=REST_TOLERANCE_RAD)
    assert _lowest_rim_z(theta) < -0.02  # the link's rim 2-3 cm inside the floor


def test_a_geometry_contact_carries_the_whole_force_on_its_link_shapes(tmp_path: Path) -> None:
    """A contact on its link's shapes (point: geometry) in MuJoCo: the floor contact is link1's cylinder, at
    rest on its rim; its force is the floor's whole push, so that the moments about the pivot balance:
    (p - pivot) x F + (c - pivot) x m g = 0 about the joint axis (p the rim point, c the centre of mass)."""
    scenario = build_scenario(_pendulum(tmp_path, True, []), with_controller=False)
    robot = MujocoRobot.build(scenario.sim_config, geometry=["floor"])
    theta, speed = _rest(robot)
    assert speed < 1e-3 and theta == pytest.approx(THETA_SHAPE, abs=REST_TOLERANCE_RAD)
    force = robot.contact_forces()[0]
    along = np.array([0.0, math.cos(theta), -math.sin(theta)])  # the link's axis
    down = np.array([0.0, -math.sin(theta), -math.cos(theta)])  # its radius towards the floor
    pivot = np.array([0.0, 0.0, PIVOT_Z])
    rim = pivot + LENGTH * along + RADIUS * down
    weight = np.array([0.0, 0.0, -MASS * 9.81])
    moment = np.cross(rim - pivot, force)[0] + np.cross(0.5 * LENGTH * along, weight)[0]
    print(f"\nf = {force} N, moment {moment:.2e} N m")
    assert force[2] > 0.0
    assert abs(moment) < 0.01 * abs(np.cross(0.5 * LENGTH * along, weight)[0])
    # Its point: on the rim, where the shape meets the floor (not the tip frame, 25 mm above it).
    assert robot.contact_points()[0] == pytest.approx(rim, abs=1e-3)


def test_a_collision_mesh_mujoco_cannot_read_is_refused_naming_it(tmp_path: Path) -> None:
    """A Collada collision mesh (pinocchio's coal reads it; MuJoCo has no decoder for it): with the shapes
    kept, MujocoRobot.build refuses the scenario before any step, naming the file and what to set."""
    from test_meshes import DAE

    from bracing_core.params import ConfigError
    from bracing_mujoco.mujoco_plant import MujocoModelError

    path = _pendulum(tmp_path, True, ["link1"])
    (tmp_path / "link.dae").write_text(DAE)
    urdf = tmp_path / "pendulum.urdf"
    text = urdf.read_text()
    cylinder = f'<cylinder radius="{RADIUS!r}" length="{LENGTH!r}"/>'
    collision = text.index("<collision>")
    urdf.write_text(text[:collision] + text[collision:].replace(cylinder, '<mesh filename="link.dae"/>', 1))
    config = build_scenario(path, with_controller=False).sim_config
    with pytest.raises(MujocoModelError, match=r"link\.dae.*robot\.collision_geometry: false") as refused:
        MujocoRobot.build(config)
    assert isinstance(refused.value, ConfigError)  # the nodes' main says it and exits, no traceback
    off = build_scenario(path, shared={"robot.collision_geometry": False}, with_controller=False).sim_config
    assert MujocoRobot.build(off).model.ngeom == 2  # knob off: the mesh dropped (the floor and the tip's sphere)
