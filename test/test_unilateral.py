"""Unilateral contacts: release when the force would pull, lift-off, inelastic touchdown."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import build_scenario

from bracing_core.model import RobotModel
from bracing_core.params import ConfigError

UNILATERAL = {"contacts.elbow.unilateral": True}


def test_bilateral_is_the_default_and_may_pull() -> None:
    sc = build_scenario({"input_mode": "torque", "contacts.elbow.desired_normal_force": -5.0})
    sim, ctl = sc.sim, sc.controller
    assert ctl is not None
    for _ in range(50):
        d = sim.step(ctl.update(sim.time, sim.position, sim.velocity).command)
        assert d.normal_force[0] == pytest.approx(-5.0, abs=1e-9)  # the plane pulls, as in the paper
    assert d.active is None and not [e for e in sim.events if e.kind in ("release", "touchdown")]


def test_release_when_the_force_would_pull() -> None:
    """Asked to pull (f_nd < 0), a unilateral contact lets go at once and the elbow lifts off."""
    sc = build_scenario({**UNILATERAL, "input_mode": "torque", "contacts.elbow.desired_normal_force": -5.0})
    sim, ctl = sc.sim, sc.controller
    assert ctl is not None
    residuals = []
    for _ in range(300):
        d = sim.step(ctl.update(sim.time, sim.position, sim.velocity).command)
        assert d.active is not None and not d.active[0]
        assert d.normal_force[0] == 0.0
        residuals.append(d.contacts.residual[0])
    assert [(e.contact, e.kind, e.time) for e in sim.events] == [("elbow", "release", 0.0)]
    assert residuals[-1] > 1e-3  # in flight above the floor


def test_touchdown_is_inelastic_without_penetration() -> None:
    """Unpowered, the arm falls from 5 cm above the floor; at touchdown the elbow is put on the
    plane, its normal velocity removed, and the kinetic energy lost is booked."""
    sc = build_scenario(
        {**UNILATERAL, "input_mode": "torque", "contacts.elbow.offset": -0.05, "contacts.elbow.friction": 0.0},
        with_controller=False,
    )
    sim, robot = sc.sim, sc.plant.robot
    elbow = robot.frame_id("elbow")
    assert not sim.active[0]  # starts released, above its plane
    zero = np.zeros(sim.n)
    energy0 = mechanical(robot, sim.position, sim.velocity)
    landed_at = None
    for k in range(600):
        sim.step(zero)
        robot.compute(sim.position, sim.velocity)
        height = robot.frame_position(elbow)[2] + 0.05  # above the plane z = -0.05
        assert height >= -1e-9, "the elbow went through the floor"  # (drift of a held contact: ~1e-12)
        if landed_at is None and sim.events:
            landed_at = k
            assert [(e.contact, e.kind) for e in sim.events] == [("elbow", "touchdown")]
            assert sim.active[0]
            assert abs(height) < 1e-12
            assert abs(float(robot.frame_jacobian(elbow)[2] @ sim.velocity)) < 1e-12  # inelastic
    assert landed_at is not None and landed_at > 10, "it never landed"
    energy = sim.energy
    assert energy.impact_loss == pytest.approx(sim.events[0].impact_loss) and energy.impact_loss > 1e-3
    # What the fall released went into damping, the impact and what is stored now. (The position
    # projection at touchdown moves the arm by at most one step of motion, so not exact.)
    books = mechanical(robot, sim.position, sim.velocity) + energy.viscous_loss + energy.impact_loss
    assert books - energy.constraint_work == pytest.approx(energy0, rel=5e-3)  # measured 1e-3; impact is 5%


def mechanical(robot: RobotModel, q: np.ndarray, dq: np.ndarray) -> float:
    return robot.kinetic_energy(q, dq) + robot.potential_energy(q)


def test_a_penetrating_start_is_still_refused() -> None:
    with pytest.raises(ConfigError, match="infeasible start: contact 'elbow'"):
        build_scenario({**UNILATERAL, "contacts.elbow.offset": 0.05}, with_controller=False)
