"""Both engines collide the same link shapes (robot.collision_geometry): the paper arm braced at link2's surface
(point: geometry) and a link dropped onto the floor (robot.collision_links), in our engine and in MuJoCo, in
process, with our controller closing the loop on each (the torque it sends is the effort MuJoCo's node applies).

MuJoCo's contacts are soft (default solref 0.02 s / damping ratio 1, solimp 0.9-0.95 over 1 mm): a shape sinks
until the constraint's spring carries the load, and its contact point is midway through that penetration. Our
engine holds a contact exactly (a constraint) and rests a kept-out link on its surface (inelastic touchdown).

1. The paper arm, torque input, the elbow contact at link2's cylinder (config/paper_4link.yaml with
   robot.collision_geometry: true, contacts.elbow.point: geometry, the start projected), 1 s. Measured: MuJoCo's
   rim contact sinks at most 0.07 mm, its point (midway through that depth) within 0.035 mm of ours along the
   normal, 0.27 mm along the floor (the elbow slides, mu 0.1: the soft elliptic cone and the steps the contact is
   off let it slide a little differently); the time-mean of f_n 9.969 N over the second (ours 10 N to 1e-6),
   10.0002 N over its last 0.3 s. The contact chatters while the elbow slides: it is off on 10 % of the steps,
   none after 0.63 s. It is stiff: MuJoCo's static depth at a force scales with its regulariser, which
   scales with the bodies' body_invweight0 (mj_diagApprox): link2's is 0.23 1/kg, where the 5 mm sphere of a
   frame contact sits on the massless elbow body's, 4.3 1/kg (0.85 mm deep at 10 N in test_mujoco_robot, 1/18
   of that here), so the rim's depth crosses 0 on the steps the sliding link bobs. Tolerances, about twice to
   three times what was measured: the point 0.1 mm along the normal, 0.6 mm along the floor; the time-mean of f_n
   within 0.1 N of f_nd (1 %), 0.01 N over the last 0.3 s; MuJoCo's contact on in at least 75 % of the steps
   and in every one of the last 0.3 s.
2. The pendulum of test_link_shapes (one cylinder link, r 0.03 m, L 0.5 m, pivot 0.3 m above the floor) dropped
   from horizontal with robot.collision_links: [link1]: ours rests on its rim at theta_shape (by hand) to 1e-9 rad,
   no deeper than 1 mm; MuJoCo rests deeper by its soft contact's static depth, the rim ~0.06 mm in, which is
   0.06 mm / (L cos(theta) - r sin(theta)) = 0.14 mrad (measured 0.141): the test asks 0 to 0.5 mrad. Before
   touchdown (0.25 s) both fall on the same track (both integrate the same rigid pendulum with RK4 at 1 ms;
   measured bit for bit equal; the test asks 1e-9 rad).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import PAPER_YAML
from test_link_shapes import THETA_SHAPE, _pendulum

from bracing_core.link_penetration import LinkPenetration
from bracing_core.rollout import build_scenario
from bracing_mujoco.mujoco_plant import MujocoRobot

F_ND = 10.0  # [N] config/paper_4link.yaml's desired normal force
STEPS = 1000  # 1 s at its 1 ms step
AT_SURFACE = {"input_mode": "torque", "robot.collision_geometry": True, "contacts.elbow.point": "geometry"}
PROJECTED = {"project_initial_position": True}  # the elbow frame is on link2's axis: its rim starts on the floor

POINT_NORMAL_TOLERANCE_M = 1e-4
POINT_ALONG_TOLERANCE_M = 6e-4
MEAN_FORCE_TOLERANCE_N = 0.1
REST_TOLERANCE_RAD = 5e-4


def _ours_braced() -> tuple[np.ndarray, np.ndarray]:
    """Our engine: (contact point [m] per step, f_n [N] per step), each at the step's start."""
    sc = build_scenario(PAPER_YAML, shared=AT_SURFACE, sim=PROJECTED)
    sim, ctl = sc.sim, sc.controller
    points, forces = [], []
    for _ in range(STEPS):
        d = sim.step(ctl.update(sim.time, sim.position, sim.velocity).command)
        points.append(d.positions[0].copy())
        forces.append(float(d.normal_force[0]))
    return np.array(points), np.array(forces)


def _mujoco_braced() -> tuple[np.ndarray, np.ndarray, float]:
    """MuJoCo with the URDF's shapes: (contact point [m] per step, NaN when off; f_n [N]; deepest [m])."""
    sc = build_scenario(PAPER_YAML, shared=AT_SURFACE, sim=PROJECTED)
    robot, ctl = MujocoRobot.build(sc.sim_config), sc.controller
    points, forces = [], []
    for _ in range(STEPS):
        points.append(robot.contact_points()[0].copy())
        forces.append(float(robot.contact_forces()[0] @ np.array([0.0, 0.0, 1.0])))
        q, dq = robot.state()
        robot.step(ctl.update(robot.time, q, dq).command)
    return np.array(points), np.array(forces), robot.max_penetration


def test_mujoco_braces_link2_at_its_surface_where_our_engine_does() -> None:
    ours, ours_force = _ours_braced()
    theirs, their_force, deepest = _mujoco_braced()
    on = ~np.isnan(theirs[:, 0])
    gap = np.abs(ours - theirs)[on]
    print(
        f"\nMuJoCo on {on.mean():.3f} of the steps (last off at {np.flatnonzero(~on)[-1]} ms), "
        f"deepest {deepest:.2e} m; "
        f"point gap along y {gap[:, 1].max():.2e} m, along z {gap[:, 2].max():.2e} m; "
        f"mean f_n ours {ours_force.mean():.6f} N, MuJoCo {their_force.mean():.4f} N, "
        f"last 0.3 s {their_force[-300:].mean():.4f} N"
    )
    np.testing.assert_allclose(ours_force, F_ND, atol=1e-6)
    assert np.all(np.abs(ours[:, 2]) < 1e-9)  # ours: link2's rim on the floor, a constraint
    # MuJoCo: on the same shape's rim (the elbow frame on link2's axis is 1-2.5 cm above the floor), sunk < 0.2 mm
    assert 0.0 < deepest < 2e-4
    assert on.mean() >= 0.75 and on[-300:].all()
    assert gap[:, 2].max() <= POINT_NORMAL_TOLERANCE_M
    assert gap[:, 0].max() <= 1e-12 and gap[:, 1].max() <= POINT_ALONG_TOLERANCE_M  # x: the arm's plane
    assert abs(their_force.mean() - F_ND) <= MEAN_FORCE_TOLERANCE_N
    assert abs(their_force[-300:].mean() - F_ND) <= 0.1 * MEAN_FORCE_TOLERANCE_N  # settled: 0.1 %


def _falls(tmp_path: Path, seconds: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The pendulum dropped, torque input, no torque: (theta [rad] below horizontal per step, ours and MuJoCo's;
    the deepest any of ours' link1 got into the floor [m])."""
    path = _pendulum(tmp_path, True, ["link1"])
    shared = {"input_mode": "torque", "bracing": False}  # the tip frame an obstacle, link1's shape kept out
    sc = build_scenario(path, shared=shared, with_controller=False)
    sim, watch = sc.sim, LinkPenetration(sc.plant, sc.sim.dynamics.engine)
    robot = MujocoRobot.build(build_scenario(path, shared=shared, with_controller=False).sim_config)
    ours, theirs = [], []
    for _ in range(round(seconds / sc.sim_config.step)):
        sim.step(np.zeros(1))
        robot.step(np.zeros(1))
        watch.measure(sim.position, sim.time)
        ours.append(float(sim.position[0]))
        theirs.append(float(robot.state()[0][0]))
    to_theta = -math.pi / 2  # q = -(pi/2 + theta)
    return to_theta - np.array(ours), to_theta - np.array(theirs), watch.deepest["link1"]


def test_a_dropped_collision_link_rests_where_mujoco_rests_it(tmp_path: Path) -> None:
    ours, theirs, deepest = _falls(tmp_path, 2.0)
    falling = slice(0, 240)  # touchdown at 0.251 s
    print(
        f"\nrest ours {ours[-1]:.6f} rad, MuJoCo {theirs[-1]:.6f} rad (by hand {THETA_SHAPE:.6f}); "
        f"falling apart {np.max(np.abs(ours[falling] - theirs[falling])):.1e} rad; ours deepest {deepest:.1e} m"
    )
    assert deepest <= 1e-3
    assert ours[-1] == pytest.approx(THETA_SHAPE, abs=1e-9)
    assert np.ptp(ours[-500:]) < 1e-9 and np.ptp(theirs[-500:]) < 1e-6  # both at rest
    assert 0.0 <= theirs[-1] - ours[-1] <= REST_TOLERANCE_RAD  # MuJoCo's rim sinks: a little further down
    np.testing.assert_allclose(ours[falling], theirs[falling], atol=1e-9)
