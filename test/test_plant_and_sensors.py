"""A plant that differs from the controller's model, sensing as a real arm has it, force feedback and
thermal compensation (docs/model.md, Model error, sensing and force feedback).

Every knob is off by default and leaves every shipped scenario's numbers as they were, bit for bit
(test/data/golden_defaults.json, written by tools/golden_defaults.py on the commit before them). The
rest is hand-checked: a stalled motor whose current answers its voltage k steps late, a filter's step
response, a sensor's bias; and the paper's claims under error: with 20 % heavier links, torque
input's force error is at least ten times smaller with force feedback; with warm windings, thermal
compensation brings voltage input's late force error back to the cold motors' one.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO_ROOT, build_scenario
from test_surfaces import point_robot_urdf

import bracing_engine as engine
from bracing_core import schema
from bracing_core.contact_config import ContactConfig
from bracing_core.contacts import Contact, ContactSet, Plane
from bracing_core.dynamics import ConstrainedDynamics, InputMode
from bracing_core.measurements import Measurements
from bracing_core.model import RobotModel
from bracing_core.motors import MotorParams
from bracing_core.params import ConfigError
from bracing_core.rollout import RunResult, run_recorded
from bracing_core.simulator import Simulator

sys.path.insert(0, str(REPO_ROOT / "tools"))
import golden_defaults

STEP = 1e-3
FEEDBACK = {"contacts.elbow.force_feedback.kp": 0.3, "contacts.elbow.force_feedback.ki": 100.0}
"""Force-feedback gains used below (the robustness study's): ki = 100 1/s corrects within ~10 ms;
kp < 1 keeps the one-step-delayed proportional loop stable (torque input: f_n answers f_cmd at once)."""


def late_force_rms(recording: RunResult, since: float) -> float:
    window = recording.time >= since - 1e-12
    error = recording.normal_force[window, 0] - recording.desired_normal_force[0]
    return float(np.sqrt(np.mean(error**2)))


# -- defaults ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("scenario", "mode"), golden_defaults.CASES)
def test_every_knob_off_leaves_every_shipped_scenario_bit_identical(scenario: str, mode: str) -> None:
    """The closed loop of each shipped scenario, in each input mode, as the commit before these knobs had it."""
    golden = json.loads((REPO_ROOT / "test" / "data" / "golden_defaults.json").read_text())
    assert golden["duration_s"] == golden_defaults.DURATION_S
    assert golden_defaults.fingerprint(scenario, mode) == golden["cases"][f"{scenario}:{mode}"]


# -- command latency on a stalled motor -------------------------------------------------------------------
@pytest.fixture(scope="module")
def point_urdf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("latency") / "point.urdf"
    path.write_text(point_robot_urdf())
    return path


RESISTANCE, INDUCTANCE = 1.0, 0.02  # [ohm], [H]: L / R = 20 ms, 20 steps (RK4 within 4e-8 A of the exponential)


def stalled_point(urdf: Path) -> Simulator:
    """The Cartesian point pressed into the floor z = 0 by its z motor: dq = 0, so L di/dt = v - R i exactly."""
    robot = RobotModel.from_urdf(urdf, gravity=(0.0, 0.0, 0.0))
    ones = np.ones(3)
    motors = MotorParams(
        ones, RESISTANCE * ones, INDUCTANCE * ones, 0 * ones, ones, 0 * ones, transmission_radius=0.01 * ones,
        thermal=False,
    )  # fmt: skip
    floor = ContactSet(robot, [Contact("floor", "tip", Plane(np.array([0.0, 0.0, 1.0])))])
    return Simulator(ConstrainedDynamics(robot, motors, floor, InputMode.VOLTAGE), STEP, np.zeros(3), np.zeros(3))


def currents(sim: Simulator, commands: list[np.ndarray], sensors: engine.Sensors | None) -> np.ndarray:
    """The z motor's current at each state, stepping the answers ``commands`` through ``sensors``' delay line."""
    out = [float(sim.current[2])]
    for command in commands:
        sim.step(sensors.delay(command) if sensors is not None else command)
        out.append(float(sim.current[2]))
    return np.array(out)


@pytest.mark.parametrize("latency", [1, 3, 5])
def test_a_command_latency_of_k_steps_applies_each_command_exactly_k_steps_late(point_urdf: Path, latency: int) -> None:
    """Answers that differ at every step: the current with latency k is the current without it, k states
    later, bit for bit, and zero (no voltage yet) for the first k states; a constant voltage from state 0
    then follows i = v / R (1 - exp(-R (t - k h) / L)) from t = k h on."""
    commands = [np.array([0.0, 0.0, -1.0 - 0.01 * m]) for m in range(60)]
    prompt = currents(stalled_point(point_urdf), commands, None)
    sensors = engine.Sensors(engine.SensorSpec(step=STEP, revolute=[False] * 3, command_latency_steps=latency), 3)
    late = currents(stalled_point(point_urdf), commands, sensors)
    assert np.all(late[: latency + 1] == 0.0)
    assert np.array_equal(late[latency:], prompt[: len(prompt) - latency])

    volts = -2.0
    sensors = engine.Sensors(engine.SensorSpec(step=STEP, revolute=[False] * 3, command_latency_steps=latency), 3)
    step_response = currents(stalled_point(point_urdf), [np.array([0.0, 0.0, volts])] * 80, sensors)
    t = np.arange(step_response.size) * STEP
    expected = np.where(
        t >= latency * STEP, volts / RESISTANCE * (1.0 - np.exp(-RESISTANCE * (t - latency * STEP) / INDUCTANCE)), 0.0
    )
    assert np.max(np.abs(step_response - expected)) < 1e-7  # RK4 at h = L/R / 20: 4e-8 A of its own


def test_a_refused_step_is_taken_back_from_the_delay_line() -> None:
    """What the simulator node does when it refuses a step: the next answer takes the refused one's place."""
    sensors = engine.Sensors(engine.SensorSpec(step=STEP, revolute=[True], command_latency_steps=2), 1)
    applied = [float(sensors.delay(np.array([v]))[0]) for v in (1.0, 2.0, 3.0)]
    sensors.take_back()  # 3.0's step refused: 1.0 goes back to the front
    applied += [float(sensors.delay(np.array([v]))[0]) for v in (4.0, 5.0, 6.0)]
    assert applied == [0.0, 0.0, 1.0, 1.0, 2.0, 4.0]


def test_the_rollout_applies_its_answers_k_steps_late() -> None:
    """The closed loop with latency 3: its states are those of the open loop stepped with its own answers,
    three states late (zero before), bit for bit."""
    latency, steps = 3, 120
    scenario = build_scenario({"input_mode": "torque"}, sim={"sensors.command_latency_steps": latency})
    recording = run_recorded(scenario, steps * STEP)
    replay = build_scenario({"input_mode": "torque"}, with_controller=False).sim
    for k in range(steps):
        replay.step(recording.command[k - latency] if k >= latency else np.zeros(replay.n))
        assert np.array_equal(replay.position, recording.position[k + 1]), k


# -- what the sensors read ----------------------------------------------------------------------------------
NOISY = {
    "sensors.position_noise_rad": 2e-4,
    "sensors.velocity_noise_rad_s": 0.01,
    "sensors.force_noise_n": 0.5,
    "sensors.force_bias_n": 0.3,
    "sensors.encoder_counts_per_rev": 8192,
}


def noisy_run(seed: int, duration: float = 0.3) -> RunResult:
    sim = {**NOISY, "sensors.noise_seed": seed}
    return run_recorded(build_scenario({"input_mode": "torque"}, sim=sim, ctl=FEEDBACK), duration)


def test_seeded_noise_reproduces_bit_for_bit_and_another_seed_differs() -> None:
    first, again, other = noisy_run(7), noisy_run(7), noisy_run(8)
    for name in ("measured_position", "measured_velocity", "position", "normal_force", "force_command"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name
    assert not np.array_equal(first.measured_position, other.measured_position)
    assert not np.array_equal(first.force_command, other.force_command)  # the force sensor's noise, fed back
    # the truth is recorded as the truth: the measured positions differ from it by the noise and a count
    error = first.measured_position - first.position
    assert 0.0 < np.abs(error).max() < 6 * 2e-4 + 2 * math.pi / 8192


def test_encoder_quantisation_puts_every_measured_q_on_the_grid() -> None:
    counts = 4096
    recording = run_recorded(
        build_scenario({"input_mode": "torque"}, sim={"sensors.encoder_counts_per_rev": counts}), 0.2
    )
    ticks = recording.measured_position / (2.0 * math.pi / counts)
    assert np.max(np.abs(ticks - np.round(ticks))) < 1e-9
    assert np.max(np.abs(recording.measured_position - recording.position)) <= math.pi / counts + 1e-12
    assert np.array_equal(recording.measured_velocity, recording.velocity)  # velocity exact unless asked


def test_differentiated_velocity_is_the_first_order_filter_of_the_difference() -> None:
    """A joint moving at a constant 2 rad/s read through a 20 Hz filter: the estimate rises as
    1 - (1 - a)^k with a = h w / (1 + h w), w = 2 pi 20 (backward Euler), from 0 at the first state."""
    cutoff, speed = 20.0, 2.0
    sensors = engine.Sensors(engine.SensorSpec(step=STEP, revolute=[True], velocity_filter_hz=cutoff), 1)
    w = 2.0 * math.pi * cutoff
    a = STEP * w / (1.0 + STEP * w)
    for k in range(200):
        _, dq = sensors.joints(np.array([speed * k * STEP]), np.array([speed]))
        assert float(dq[0]) == pytest.approx(speed * (1.0 - (1.0 - a) ** k), rel=1e-9, abs=1e-12), k


def test_a_force_sensor_reads_the_force_plus_its_bias_along_the_normal_plus_noise() -> None:
    sigma, bias, samples = 0.5, 0.3, 20000
    sensors = engine.Sensors(
        engine.SensorSpec(step=STEP, revolute=[True], seed=3, force_noise=sigma, force_bias=bias), 1
    )
    force, normal = np.array([1.0, -2.0, 10.0]), np.array([0.0, 0.6, 0.8])
    readings = np.array([sensors.force(force, normal) for _ in range(samples)])
    assert np.allclose(readings.mean(axis=0), force + bias * normal, atol=4 * sigma / math.sqrt(samples))
    assert np.allclose(readings.std(axis=0), sigma, rtol=0.03)
    exact = engine.Sensors(engine.SensorSpec(step=STEP, revolute=[True]), 1)
    assert np.array_equal(exact.force(force, normal), force) and exact.exact


# -- force feedback ------------------------------------------------------------------------------------------
def test_force_feedback_changes_nothing_with_a_perfect_model() -> None:
    """Torque input on the exact model: f_n = f_nd at every step, so the feedback's error is zero (it still
    reads the force: the first state has none to read)."""
    recording = run_recorded(build_scenario({"input_mode": "torque"}, ctl=FEEDBACK), 1.0)
    assert np.max(np.abs(recording.normal_force[:, 0] - 10.0)) < 1e-9
    assert np.max(np.abs(recording.force_command[:, 0] - 10.0)) < 1e-9


def test_force_feedback_shrinks_the_force_error_of_heavier_links_tenfold() -> None:
    """Every link 20 % heavier in the plant than in the controller's model: torque input no longer
    keeps f_n = f_nd (the law's B and a are off); fed back, the measured force tracks f_nd again."""
    heavy = {"plant_error.mass_scale": 1.2}
    without = run_recorded(build_scenario({"input_mode": "torque"}, sim=heavy), 3.0)
    with_feedback = run_recorded(build_scenario({"input_mode": "torque"}, sim=heavy, ctl=FEEDBACK), 3.0)
    before, after = late_force_rms(without, 2.0), late_force_rms(with_feedback, 2.0)
    assert before > 0.5  # the model error shows (measured: 2.0 N)
    assert after * 10.0 <= before, (before, after)


def test_force_feedback_trusts_its_sensor_a_bias_moves_the_true_force() -> None:
    """The loop drives the *measured* force to f_nd: with a 0.4 N sensor bias on the exact model the true
    force settles at f_nd - 0.4 N (docs/model.md, the feedback's limits)."""
    recording = run_recorded(
        build_scenario({"input_mode": "torque"}, sim={"sensors.force_bias_n": 0.4}, ctl=FEEDBACK), 3.0
    )
    late = recording.normal_force[recording.time >= 2.0, 0]
    assert float(late.mean()) == pytest.approx(10.0 - 0.4, abs=1e-3)
    assert float(late.std()) < 1e-3


def test_the_integral_holds_while_the_commands_saturate() -> None:
    """Anti-windup: with a torque limit every command reaches, the integral never grows from its start at
    zero, so an integral-only feedback asks for f_nd throughout; without the limit it does not."""
    heavy = {"plant_error.mass_scale": 1.2}
    integral = {"contacts.elbow.force_feedback.ki": 100.0}
    free = run_recorded(build_scenario({"input_mode": "torque"}, sim=heavy, ctl=integral), 0.2)
    limited = run_recorded(
        build_scenario({"input_mode": "torque", "motors.torque_limit": 1e-3}, sim=heavy, ctl=integral), 0.2
    )
    assert np.any(free.force_command[:, 0] != 10.0)
    assert np.all(limited.force_command[:, 0] == 10.0)


# -- thermal compensation ---------------------------------------------------------------------------------------
def test_thermal_compensation_brings_voltage_input_back_to_the_cold_motors_force_error() -> None:
    """Voltage input over the paper's 10 s: warm windings conduct less than K_V assumes, and the late force
    error grows (measured 0.87 -> 1.52 N RMS after 5 s); K_V R(T) / R_20 brings it within 10 % of thermal: false."""
    cold = run_recorded(build_scenario({"motors.thermal": False}), 10.0)
    warm = run_recorded(build_scenario(), 10.0)
    compensated = run_recorded(build_scenario(ctl={"voltage_law.thermal_compensation": True}), 10.0)
    reference = late_force_rms(cold, 5.0)
    assert late_force_rms(warm, 5.0) > 1.3 * reference
    assert abs(late_force_rms(compensated, 5.0) - reference) <= 0.1 * reference
    assert compensated.temperature.max() > 40.0  # the windings did warm


# -- the plant's own numbers ----------------------------------------------------------------------------------
def test_plant_error_reaches_the_simulated_plant_only() -> None:
    errors = {
        "plant_error.mass_scale": 1.3,
        "plant_error.friction_scale": 2.0,
        "plant_error.torque_constant_scale": 0.9,
        "plant_error.resistance_scale": 1.1,
    }
    torque = {"input_mode": "torque"}  # no rotor inertia: the plant's M and g are exactly 1.3 times the model's
    nominal, scenario = build_scenario(torque), build_scenario(torque, sim=errors)
    assert scenario.controller is not None and nominal.controller is not None
    plant, model = scenario.plant, scenario.controller.plant
    masses = [float(i.mass) for i in plant.robot.model.inertias][1:]
    assert masses == pytest.approx([1.3 * float(i.mass) for i in model.robot.model.inertias][1:])
    assert np.allclose(plant.motors.torque_constant, 0.9 * model.motors.torque_constant)  # (unused in torque mode)
    assert np.allclose(plant.motors.resistance, 1.1 * model.motors.resistance)
    assert plant.contact_set.contacts[0].friction == pytest.approx(2.0 * model.braced_set.contacts[0].friction)
    # the engine's plant is the heavier one: the floor carries 1.3x the arm's weight with no torque at all
    zero = np.zeros(plant.robot.nv)
    heavier = scenario.sim.evaluate(zero).normal_force[0]
    assert heavier == pytest.approx(1.3 * nominal.sim.evaluate(zero).normal_force[0], rel=1e-12)


def test_bad_knobs_are_refused_naming_them(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"plant_error\.urdf"):
        build_scenario(sim={"plant_error.urdf": str(tmp_path / "missing.urdf")})
    with pytest.raises(ConfigError, match=r"sensors\.force_noise_n"):
        build_scenario(sim={"sensors.force_noise_n": -1.0})
    with pytest.raises(ConfigError, match=r"sensors\.command_latency_steps"):
        build_scenario(sim={"sensors.command_latency_steps": -2})
    with pytest.raises(ConfigError, match=r"contacts\.knee\.force_feedback"):  # an obstacle has no force to feed back
        ContactConfig.from_values("knee", schema.contact_values({"frame": "link2", "force_feedback.ki": 10.0}))
    knee = schema.contact_values({"frame": "link2", "force_feedback.ki": 10.0})
    passive = ContactConfig.from_values("knee", knee, bracing=False)
    assert passive.feedback_ki == 0.0  # --no-bracing: no force, so nothing fed back (as brace_axes are dropped)


def test_a_plant_urdf_of_its_own_is_simulated(tmp_path: Path) -> None:
    """plant_error.urdf: the paper arm with a 2 kg first link, the controller on the 1 kg one."""
    text = (REPO_ROOT / "config" / "paper_4link.urdf").read_text()
    heavier = text.replace('<mass value="1.0"/>', '<mass value="2.0"/>', 1)
    assert heavier != text
    path = tmp_path / "plant.urdf"
    path.write_text(heavier)
    scenario = build_scenario(sim={"plant_error.urdf": str(path)})
    assert scenario.controller is not None
    plant = [float(i.mass) for i in scenario.plant.robot.model.inertias]
    model = [float(i.mass) for i in scenario.controller.plant.robot.model.inertias]
    assert plant != model and sum(plant) == pytest.approx(sum(model) + 1.0)


# -- which measurement a state is answered with (the controller node's policy, no DDS) ----------------------------
def test_a_state_waits_for_the_reports_of_the_step_before_it() -> None:
    controller = build_scenario(ctl={**FEEDBACK, "voltage_law.thermal_compensation": True}).controller
    assert controller is not None
    measurements = Measurements.for_law(controller)
    assert measurements is not None and measurements.forces == ["elbow"] and measurements.temperature
    assert measurements.ready(None)  # the first state: nothing to wait for
    assert not measurements.ready(0)
    assert measurements.take_force("elbow", 0, np.array([0.0, 0.0, 9.0])) is None
    assert measurements.missing(0) == ["motor_state"]
    assert measurements.take_temperature(0, np.full(4, 30.0), 4) is None
    assert measurements.ready(0) and not measurements.ready(1_000_000)
    assert "finite" in (measurements.take_force("elbow", 1, np.array([math.nan, 0.0, 0.0])) or "")
    assert "3 temperatures, not 4" in (measurements.take_temperature(1, np.zeros(3), 4) or "")
    assert "world axes" in (measurements.take_force("elbow", 1, np.zeros(3), "ft_sensor") or "")
    assert not measurements.ready(1)  # the refused ones were not kept
    paper = build_scenario().controller
    assert paper is not None
    assert Measurements.for_law(paper) is None  # the paper's law reads nothing but the joints
