"""Coulomb friction with a stick phase (docs/model.md, Friction): hand-checked cases on a point
mass on a plane, a stick whose time is known in closed form, convergence of the paper's run with
the step, and the law's exact normal force in both phases.

The point mass rides three prismatic carriages (x, y, z; test_surfaces.point_robot_urdf) and
rests on the floor z = 0 under gravity: f_n = m_z g. A force on the x joint pushes it along the
floor, where it moves the x carriage's mass m_x (all three carriages).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import build_scenario
from test_surfaces import LIGHT, MASS, motors, point_robot_urdf

from bracing_core.contacts import Contact, ContactSet, Plane
from bracing_core.dynamics import ConstrainedDynamics, InputMode
from bracing_core.model import RobotModel
from bracing_core.rollout import run_recorded
from bracing_core.simulator import Simulator

G = 9.81
MU = 0.4
M_X = 2 * LIGHT + MASS  # what a push along x accelerates
F_N = MASS * G  # what the floor holds


@pytest.fixture(scope="module")
def urdf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("block") / "block.urdf"
    path.write_text(point_robot_urdf())
    return path


def block(urdf: Path, velocity_x: float = 0.0, model: str = "coulomb", step: float = 1e-3) -> Simulator:
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, -G))
    floor = Contact("floor", "tip", Plane(np.array([0.0, 0.0, 1.0])), MU, friction_model=model)
    dynamics = ConstrainedDynamics(robot, motors(), ContactSet(robot, [floor]), InputMode.TORQUE)
    return Simulator(dynamics, step, np.zeros(3), np.array([velocity_x, 0.0, 0.0]))


def test_a_push_inside_the_cone_leaves_the_block_where_it_is(urdf: Path) -> None:
    """F = 0.6 mu f_n: the block sticks, and friction holds exactly F back (not mu f_n)."""
    sim = block(urdf)
    push = 0.6 * MU * F_N
    for _ in range(1000):
        d = sim.step(np.array([push, 0.0, 0.0]))
    assert d.sticking[0] and d.normal_force[0] == pytest.approx(F_N, rel=1e-12)
    assert d.tangential_force[0] == pytest.approx([-push, 0.0, 0.0], abs=1e-9)
    assert abs(sim.position[0]) < 1e-12 and abs(sim.velocity[0]) < 1e-12
    assert not sim.events
    assert sim.energy.friction_loss == pytest.approx(0.0, abs=1e-12)  # no work while it sticks


def test_a_push_beyond_the_cone_slides_it_at_the_coulomb_rate(urdf: Path) -> None:
    """F = 2 mu f_n: the block breaks away at once and accelerates at (F - mu f_n) / m_x; the
    friction it works against is booked as friction loss, mu f_n x."""
    sim = block(urdf)
    push = 2.0 * MU * F_N
    for _ in range(1000):
        d = sim.step(np.array([push, 0.0, 0.0]))
    acceleration = (push - MU * F_N) / M_X
    t = sim.time
    assert [(e.kind.name, e.time) for e in sim.events] == [("slip", 0.0)]
    assert not d.sticking[0] and d.friction_force[0] == pytest.approx(MU * F_N, rel=1e-12)
    assert sim.position[0] == pytest.approx(0.5 * acceleration * t**2, rel=1e-12)
    assert sim.velocity[0] == pytest.approx(acceleration * t, rel=1e-12)
    assert sim.energy.friction_loss == pytest.approx(MU * F_N * sim.position[0], rel=1e-9)


def test_a_sliding_block_sticks_when_its_slip_ends_inside_a_step(urdf: Path) -> None:
    """Launched at v0 with no push, the block decelerates at mu f_n / m_x and sticks at
    t* = v0 m_x / (mu f_n), inside a step: the event lands there, it stops at v0^2 / (2 a) and stays;
    its kinetic energy went into friction (the books close)."""
    v0 = 0.37
    sim = block(urdf, velocity_x=v0)
    deceleration = MU * F_N / M_X
    stop = v0 / deceleration
    assert stop / sim.step_size % 1.0 > 0.1  # not on a step's boundary
    for _ in range(int(stop / sim.step_size) + 200):
        sim.step(np.zeros(3))
    (event,) = sim.events
    # (located where the slip has reversed by the 1e-10 m/s the engine counts as rest: 2.6e-11 s late)
    assert event.kind.name == "stick" and event.time == pytest.approx(stop, abs=1e-10)
    assert sim.position[0] == pytest.approx(v0**2 / (2.0 * deceleration), rel=1e-12)
    assert abs(sim.velocity[0]) < 1e-15 and sim.sticking[0]
    kinetic = 0.5 * M_X * v0**2
    assert sim.energy.friction_loss == pytest.approx(kinetic, rel=1e-9)


def test_the_regularised_law_is_still_there_and_creeps(urdf: Path) -> None:
    """friction_model: regularized, the paper's law: below the cone the block creeps, in steady state
    at the s where mu f_n s / sqrt(s^2 + eps^2) = F: s = eps x / sqrt(1 - x^2), x = F / (mu f_n)."""
    sim = block(urdf, model="regularized", step=1e-4)
    push = 0.5 * MU * F_N
    for _ in range(3000):
        sim.step(np.array([push, 0.0, 0.0]))
    x = push / (MU * F_N)
    assert sim.velocity[0] == pytest.approx(1e-4 * x / np.sqrt(1.0 - x * x), rel=1e-6)  # eps = 1e-4 m/s


def test_the_paper_run_converges_with_the_step() -> None:
    """The paper's 10 s run (voltage, mu = 0.1, Coulomb): 1 and 16 sub-steps agree to 1e-5 rad in q
    and 1e-2 N in the normal and friction forces (measured: 8e-10 rad, 1e-6 N, 3e-7 N). The
    regularised law misses both by far (6.7e-4 rad, 1.4 N), which is why it is no longer the default."""
    runs = [run_recorded(build_scenario({}, {"substeps": substeps}), 10.0) for substeps in (1, 16)]
    coarse, fine = runs
    assert np.max(np.abs(coarse.position - fine.position)) < 1e-5
    assert np.max(np.abs(coarse.normal_force - fine.normal_force)) < 1e-2
    assert np.max(np.abs(coarse.friction_force - fine.friction_force)) < 1e-2
    sticking = np.linalg.norm(fine.slip_velocity[:, 0], axis=1) < 1e-10
    assert 0.05 < sticking.mean() < 0.95  # both phases are in it


def test_torque_input_holds_f_nd_while_the_elbow_sticks_and_slides() -> None:
    """The paper's headline property with Coulomb friction: with torque input f_n = f_nd at every
    step, in stick (the law's point-constraint model, its tangential force kept in the cone) and in
    slip (the law's Coulomb slide direction)."""
    sc = build_scenario({"input_mode": "torque"})
    rec = run_recorded(sc, 10.0)
    assert np.max(np.abs(rec.normal_force[:, 0] - rec.desired_normal_force[0])) < 1e-8
    sticking = np.linalg.norm(rec.slip_velocity[:, 0], axis=1) < 1e-10
    assert sticking.sum() > 100 and (~sticking).sum() > 100
    kinds = {event.kind.name for event in sc.sim.events}
    assert kinds == {"stick", "slip"}


def test_a_step_started_from_the_last_steps_end_evaluation_is_the_freshly_evaluated_one() -> None:
    """With voltage input the engine takes a step's end evaluation as the next step's first stage (only
    the circuit redone under the new command); forgetting it before every step (set_state) gives the
    same run bit for bit: states and reports, through a slip and a stick."""
    runs = []
    for fresh in (False, True):
        sim = build_scenario({}, with_controller=False).sim
        engine = sim.engine
        rng = np.random.default_rng(0)
        rows = []
        for _ in range(400):
            if fresh:
                engine.set_state(engine.state)
            answer = engine.step(rng.normal(0.0, 3.0, sim.n)).answer
            assert answer is not None
            state = engine.state
            blocks = [state.position, state.velocity, state.current, state.temperature, state.energy]
            forces = [answer.normal_force, answer.friction_force]
            rows.append(np.concatenate([*blocks, answer.acceleration, answer.current_rate, *forces]))
        assert {event.kind.name for event in engine.events_since(0, 0)} == {"stick", "slip"}
        runs.append(np.array(rows))
    assert np.array_equal(runs[0], runs[1])
