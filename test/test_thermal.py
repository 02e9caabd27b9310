"""The motors' thermal model (docs/model.md, Motor thermal model) against hand-checked answers.

A stalled motor carries a constant current, so its winding obeys a scalar ODE with a closed-form
answer: the Cartesian point of test_surfaces pressed into the floor by its z motor (the floor holds
it: dq = 0, so no back-EMF) has i = v / R(T). With alpha = 0 that is a constant heat R i^2 and
T(t) = T_ss - (T_ss - T_0) exp(-t / tau), tau = R_th C_th, T_ss = T_a + R_th R i^2; with
alpha > 0 a hotter winding conducts less, and the steady state solves
(T - T_a) / R_th = v^2 / R(T), a quadratic in T. Then the books: the heat stored in the windings
plus the heat given to the ambient is the copper loss the energy integrals count, on the paper's
run; and ``thermal: false`` is the old model exactly.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import build_scenario
from test_surfaces import point_robot_urdf

from bracing_core.contacts import Contact, ContactSet, Plane
from bracing_core.dynamics import ConstrainedDynamics, InputMode
from bracing_core.model import RobotModel
from bracing_core.motors import MotorParams
from bracing_core.rollout import run_recorded
from bracing_core.simulator import WINDING_TEMPERATURE_LIMIT, DivergenceError, Simulator

R_20 = 1.0  # [ohm] at 20 degC
VOLTAGE = -2.0  # [V] on the z motor: presses the point into the floor
R_TH = 3.0  # [K/W]
C_TH = 0.2  # [J/K]: tau = 0.6 s, so that a few seconds reach the steady state
AMBIENT = 25.0  # [degC]
INDUCTANCE = 1e-3  # [H]: L / R = 1 ms, the current settles within the first 0.1 s


@pytest.fixture(scope="module")
def urdf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("stall") / "point.urdf"
    path.write_text(point_robot_urdf())
    return path


def stalled(urdf: Path, alpha: float) -> Simulator:
    """The point on the floor z = 0, gravity off, motors in voltage mode, every winding at ambient."""
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, 0.0))
    ones = np.ones(3)
    motors = MotorParams(
        ones,
        R_20 * ones,
        INDUCTANCE * ones,
        0 * ones,
        ones,
        0 * ones,
        transmission_radius=0.01 * ones,
        thermal_resistance=R_TH * ones,
        heat_capacity=C_TH * ones,
        ambient_temperature=AMBIENT,
        temperature_coefficient=alpha,
    )
    floor = ContactSet(robot, [Contact("floor", "tip", Plane(np.array([0.0, 0.0, 1.0])))])
    dynamics = ConstrainedDynamics(robot, motors, floor, InputMode.VOLTAGE)
    return Simulator(dynamics, 1e-3, np.zeros(3), np.zeros(3))


def run(sim: Simulator, seconds: float) -> np.ndarray:
    """Temperatures after each 1 ms step, (steps, 3)."""
    out = []
    for _ in range(round(seconds / 1e-3)):
        sim.step(np.array([0.0, 0.0, VOLTAGE]))
        out.append(sim.temperature.copy())
    return np.array(out)


def test_a_stalled_winding_heats_along_the_exponential(urdf: Path) -> None:
    """alpha = 0: i = v / R_20 once the current settles, and from then on T follows
    T_ss - (T_ss - T(t0)) exp(-(t - t0) / tau); the idle x and y motors stay at ambient."""
    sim = stalled(urdf, alpha=0.0)
    run(sim, 0.1)
    assert sim.velocity == pytest.approx(np.zeros(3), abs=1e-12)  # stalled: the floor holds it
    assert sim.current[2] == pytest.approx(VOLTAGE / R_20, rel=1e-12)
    t0, start = sim.time, sim.temperature[2]
    tau = R_TH * C_TH
    steady = AMBIENT + R_TH * VOLTAGE**2 / R_20
    temperature = run(sim, 3.0)
    t = t0 + 1e-3 * np.arange(1, len(temperature) + 1)
    expected = steady - (steady - start) * np.exp(-(t - t0) / tau)
    assert np.max(np.abs(temperature[:, 2] - expected)) < 1e-9 * steady
    assert temperature[-1, 2] > AMBIENT + 0.99 * (steady - AMBIENT) * (1 - math.exp(-3.0 / tau))
    assert np.all(temperature[:, :2] == AMBIENT)  # no current, no heat


def test_copper_heats_less_as_it_warms_and_settles_where_heat_in_equals_heat_out(urdf: Path) -> None:
    """alpha = 0.00393 /K: R(T) = R_20 (1 + alpha (T - 20)), i = v / R(T); the steady state is the root
    of alpha T^2 + (1 - 20 alpha - alpha T_a) T - (1 - 20 alpha) T_a - R_th v^2 / R_20 = 0 (from
    (T - T_a) R(T) = R_th v^2), below the alpha = 0 answer, and the current there is v / R(T_ss)."""
    alpha = 0.00393
    sim = stalled(urdf, alpha)
    temperature = run(sim, 12.0)  # 20 tau
    a, b = alpha, 1 - 20 * alpha - alpha * AMBIENT
    c = -(1 - 20 * alpha) * AMBIENT - R_TH * VOLTAGE**2 / R_20
    steady = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
    assert temperature[-1, 2] == pytest.approx(steady, rel=1e-9)
    assert steady < AMBIENT + R_TH * VOLTAGE**2 / R_20 - 0.5  # it matters: 0.7 K cooler than alpha = 0
    resistance = R_20 * (1 + alpha * (steady - 20.0))
    assert sim.current[2] == pytest.approx(VOLTAGE / resistance, rel=1e-9)
    assert np.all(np.diff(temperature[:, 2]) > 0)  # it only ever warms towards it


def test_the_windings_store_and_shed_exactly_the_copper_loss_the_books_count() -> None:
    """Paper arm, braced, 2 s in voltage mode: sum_j C_j (T_j(t) - T_a) + int sum_j (T_j - T_a) / R_th dt
    equals the energy integrals' copper loss int R(T) i^2 dt (trapezoid on the 1 ms samples)."""
    scenario = build_scenario({"input_mode": "voltage"})
    motors = scenario.plant.motors  # model joint order, as recorded
    recording = run_recorded(scenario, 2.0)
    temperature = recording.temperature
    assert temperature.shape == recording.current.shape
    rise = temperature - motors.ambient_temperature
    stored = rise[-1] @ motors.heat_capacity
    shed = np.sum(np.trapezoid(rise / motors.thermal_resistance, recording.time, axis=0))
    copper = recording.copper_loss[-1]
    assert copper > 1.0  # the windings did heat
    assert stored + shed == pytest.approx(copper, rel=1e-6)
    assert np.all(rise[-1] > 0.0)


def test_without_the_thermal_model_the_run_is_the_fixed_resistance_one() -> None:
    """``thermal: false`` keeps R at R_20 and records no temperature; with the model on and alpha = 0
    R(T) = R_20 too, so the two runs are the same run, bit for bit."""
    off = build_scenario({"input_mode": "voltage", "motors.thermal": False})
    flat = build_scenario({"input_mode": "voltage", "motors.temperature_coefficient": 0.0})
    a, b = run_recorded(off, 0.5), run_recorded(flat, 0.5)
    assert a.temperature.shape[1] == 0 and b.temperature.shape[1] == 4
    assert np.array_equal(a.position, b.position) and np.array_equal(a.current, b.current)
    assert a.copper_loss[-1] == b.copper_loss[-1]


def test_torque_input_has_no_windings_to_heat() -> None:
    scenario = build_scenario({"input_mode": "torque"})
    assert not scenario.plant.thermal
    assert run_recorded(scenario, 0.05).temperature.shape[1] == 0


def test_thermal_parameters_refuse_nonsense() -> None:
    ones = np.ones(2)
    base = MotorParams(ones, ones, ones, 0 * ones, ones, 0 * ones)
    for bad in ({"heat_capacity": np.array([1.0, 0.0])}, {"thermal_resistance": np.array([-1.0, 1.0])}):
        with pytest.raises(ValueError, match="must be > 0"):
            replace(base, **bad)
    with pytest.raises(ValueError, match="temperature_coefficient"):
        replace(base, temperature_coefficient=-0.1)


def test_a_command_that_would_burn_the_winding_is_refused(urdf: Path) -> None:
    """Past WINDING_TEMPERATURE_LIMIT (copper melts at 1085 degC) the step is refused as a diverged
    one is, naming the temperature: R(T) / L would otherwise make every later step too stiff for RK4."""
    sim = stalled(urdf, alpha=0.00393)
    sim.step(np.array([0.0, 0.0, -1e5]))  # 1e5 A through 1 ohm: 1e10 W into 0.2 J/K
    assert sim.temperature[2] > WINDING_TEMPERATURE_LIMIT
    with pytest.raises(DivergenceError, match=r"winding would reach .* degC"):
        sim.check(divergence_speed=1e3, divergence_residual=1.0)
