"""A real arm out of the box: geared motors with stiff circuits at the default 1 ms step, a
voltage law that inverts the motor, and a null space that stays put.

The geared arm is the paper's 4-link arm with small servo motors behind a 100:1 gear (K 0.1 N m/A,
R 0.5 ohm, L 0.1 mH: L / R = 0.2 ms, I_m 1e-6 kg m^2): its back-EMF alone is 200 N m s/rad of damping on
every joint. The free wrist is the same arm with a fifth, light joint rolling about the last link's axis:
it moves no task point, so the paper's law gives it no torque of its own.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import CONFIG_DIR, build_scenario
from ros_helpers import pair_argv, run

from bracing_core.checks import NULL_SPACE_SPEED, null_space_warning
from bracing_core.config import circuit_substeps
from bracing_core.rollout import RunResult, run_recorded
from bracing_core.simulator import JointLimitError


def geared(inductance: float = 1e-4) -> dict[str, Any]:
    return {
        "motors.gear_ratio": [100.0] * 4,
        "motors.torque_constant": [0.1] * 4,
        "motors.resistance": [0.5] * 4,
        "motors.inductance": [inductance] * 4,
        "motors.rotor_inertia": [1e-6] * 4,
        "motors.gear_damping": [1e-5] * 4,
    }


BEMF = {"voltage_law.back_emf_compensation": True}


def hand_rms(recording: RunResult, since: float = 2.0) -> float:
    window = recording.time >= since - 1e-12
    error = np.linalg.norm(recording.hand_desired[window] - recording.hand_actual[window], axis=1)
    return float(np.sqrt(np.mean(error**2)))


def force_rms(recording: RunResult, since: float = 2.0) -> float:
    window = recording.time >= since - 1e-12
    return float(np.sqrt(np.mean((recording.normal_force[window, 0] - recording.desired_normal_force[0]) ** 2)))


# -- stiff circuits at 1 ms ---------------------------------------------------------------------------------
def test_the_papers_motors_need_no_sub_step_and_a_geared_servo_gets_its_own() -> None:
    paper = build_scenario(with_controller=False)
    assert circuit_substeps(paper.plant, paper.sim.position, 1e-3) == 1  # so every paper number is as it was
    assert paper.sim.substeps == 1
    servo = build_scenario(geared(), with_controller=False)
    assert servo.sim.substeps == circuit_substeps(servo.plant, servo.sim.position, 1e-3) == 12
    torque = build_scenario({**geared(), "input_mode": "torque"}, with_controller=False)
    assert torque.sim.substeps == 1  # no circuit in torque input


@pytest.mark.parametrize("inductance", [1e-4, 2.5e-5])
def test_stiff_circuits_run_at_1_ms_and_converge_to_16_sub_steps(inductance: float) -> None:
    """L / R = 0.2 ms and 0.05 ms at the default 1 ms step (classic RK4 alone diverged at t = 3 ms): the run
    with the sub-steps the circuits need agrees with the 16-sub-step one over 1 s to the stated tolerances
    (measured: 4e-7 rad and 9e-4 N at 0.2 ms; 7e-7 rad and 4e-3 N at 0.05 ms), and its energy to 1e-4."""
    shared = geared(inductance)
    default = run_recorded(build_scenario(shared, ctl=BEMF), 1.0)
    fine = run_recorded(build_scenario(shared, sim={"substeps": 16}, ctl=BEMF), 1.0)
    assert np.max(np.abs(default.position - fine.position)) < 1e-5  # [rad]
    assert np.max(np.abs(default.normal_force - fine.normal_force)) < 1e-2  # [N]
    assert abs(default.energy_consumed[-1] / fine.energy_consumed[-1] - 1.0) < 1e-4


def test_the_energy_books_of_a_stiff_geared_arm_close() -> None:
    """With the sub-steps its circuits need: int v i = copper + d(L i^2 / 2) + d(KE + PE) + d(rotor KE) +
    viscous + friction + impacts - constraint work, over 1 s of the inverted-motor law."""
    scenario = build_scenario(geared(), ctl=BEMF)
    sim, plant, controller = scenario.sim, scenario.plant, scenario.controller
    assert controller is not None and sim.substeps == 12
    motors, robot = plant.motors, plant.robot

    def stored() -> float:
        q, dq, i = sim.position, sim.velocity, sim.current
        mechanical = robot.kinetic_energy(q, dq) + robot.potential_energy(q)
        return mechanical + 0.5 * float(dq @ (motors.reflected_inertia * dq)) + 0.5 * float(i @ (motors.inductance * i))

    start = stored()
    for _ in range(1000):
        sim.step(controller.update(sim.time, sim.position, sim.velocity).command)
    e = sim.energy
    books = e.copper_loss + (stored() - start) + e.viscous_loss + e.friction_loss + e.impact_loss - e.constraint_work
    assert e.net == pytest.approx(books, rel=2e-4, abs=1e-6)
    assert e.consumed > 1.0


# -- the motor inverted ---------------------------------------------------------------------------------------
def test_the_back_emf_law_is_the_motor_model_inverted() -> None:
    """v = R tau / K_m + K_m dq per joint (R_20 without thermal compensation), K_V unused."""
    scenario = build_scenario(geared(), ctl={**BEMF, "voltage_gain": [7.0] * 4})
    controller = scenario.controller
    assert controller is not None
    q, dq = scenario.sim.position, np.array([0.3, -0.2, 0.5, 0.1])
    out = controller.update(0.0, q, dq)
    motors = controller.plant.motors
    expected = motors.resistance * out.torque / motors.reflected_constant + motors.reflected_constant * dq
    np.testing.assert_allclose(out.command, expected, rtol=1e-14, atol=1e-12)


def test_on_a_geared_arm_the_inverted_motor_tracks_like_torque_input() -> None:
    """The paper's v = K_V tau leaves the back-EMF's 200 N m s/rad in the loop: the force error is tens of
    newtons. The motor inverted tracks the hand within 2x of torque input (measured: 37 vs 48 mm RMS after
    2 s) and the force within 1 N (0.31 N)."""
    duration = 2.5
    torque = run_recorded(build_scenario({**geared(), "input_mode": "torque"}), duration)
    paper = run_recorded(build_scenario(geared()), duration)
    inverted = run_recorded(build_scenario(geared(), ctl=BEMF), duration)
    assert force_rms(paper) > 20.0
    assert hand_rms(inverted) <= 2.0 * hand_rms(torque)
    assert force_rms(inverted) < 1.0


# -- a null space that stays put --------------------------------------------------------------------------------
WRIST = """  <joint name="wrist" type="revolute">
    <parent link="link4"/>
    <child link="gripper"/>
    <origin xyz="0 0 0.5" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-3.0" upper="3.0" effort="100.0" velocity="100.0"/>
    <dynamics damping="0.0" friction="0.0"/>
  </joint>
  <link name="gripper">
    <inertial>
      <origin xyz="0.05 0 0.03" rpy="0 0 0"/>
      <mass value="0.2"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/>
    </inertial>
  </link>
</robot>"""
REST = 0.3  # [rad] the wrist's start


def wrist_params(tmp_path: Path, ctl: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """(shared, simulator, controller) overrides of the paper scenario for the arm with a free wrist."""
    urdf = tmp_path / "wrist.urdf"
    urdf.write_text((CONFIG_DIR / "paper_4link.urdf").read_text().replace("</robot>", WRIST))

    def five(value: float) -> list[float]:
        return [value] * 5

    motors = {f"motors.{name}": five(value) for name, value in (("torque_constant", 0.2), ("resistance", 0.6))}
    motors |= {f"motors.{name}": five(value) for name, value in (("inductance", 0.17), ("rotor_inertia", 1.64e-4))}
    motors |= {f"motors.{name}": five(value) for name, value in (("gear_ratio", 3.0), ("gear_damping", 0.1))}
    motors |= {f"motors.{name}": five(value) for name, value in (("transmission_radius", 0.0),)}
    motors |= {"motors.thermal_resistance": five(3.0), "motors.heat_capacity": five(70.0)}
    shared = {"robot.urdf": str(urdf), "robot.joint_names": ["joint1", "joint2", "joint3", "joint4", "wrist"]}
    start = [-0.6283185307179586, -1.8849555921538759, 2.5132741228718345, -1.2566370614359172, REST]
    sim = {"initial_position": start, "initial_velocity": five(0.0)}
    own = {"voltage_gain": five(1.0), "null_space_posture.kp": five(0.0), "null_space_posture.kd": five(0.0), **ctl}
    return {**shared, **motors, "input_mode": "torque"}, sim, own


def wrist_arm(tmp_path: Path, ctl: dict[str, Any]) -> RunResult:
    shared, sim, own = wrist_params(tmp_path, ctl)
    return run_recorded(build_scenario(shared, sim=sim, ctl=own), 3.0)


def test_a_free_wrist_runs_away_without_a_posture_task_and_stays_with_one(tmp_path: Path) -> None:
    """The wrist moves no task point: in the paper's null space it is driven by the contact torques (B^+ puts
    them on the lightest joint) and spins to its limit within 0.1 s; in the dynamically consistent one it
    drifts there within 0.4 s. A posture task (kp 1 N m/rad, kd 0.2 N m s/rad on the wrist) holds it within
    0.15 rad of its start, the hand still on its path and f_n = f_nd."""
    consistent = {"null_space": "dynamically_consistent"}
    for law in ({}, consistent):
        with pytest.raises(JointLimitError, match="wrist"):
            wrist_arm(tmp_path, law)
    posture = {"null_space_posture.kp": [0.0] * 4 + [1.0], "null_space_posture.kd": [0.0] * 4 + [0.2]}
    held = wrist_arm(tmp_path, {**consistent, **posture})
    assert np.max(np.abs(held.position[:, 4] - REST)) < 0.15
    assert hand_rms(held) < 0.03
    assert np.max(np.abs(held.normal_force[:, 0] - 10.0)) < 1e-9
    paper = wrist_arm(tmp_path, posture)  # the paper's B^+ still shakes it, but it stays off its limits
    assert np.max(np.abs(paper.position[:, 4])) < 3.0


def test_a_null_space_running_on_its_own_is_warned_about() -> None:
    assert null_space_warning(NULL_SPACE_SPEED * 1.5, 0.005, 0.1) is not None
    warning = null_space_warning(10.0, 0.001, 0.25)
    assert warning is not None and "null_space_posture.kd" in warning and "0.250" in warning
    assert null_space_warning(NULL_SPACE_SPEED * 0.5, 0.001, 0.1) is None  # slow: no news
    assert null_space_warning(10.0, 0.05, 0.1) is None  # the hand is off its path: the tasks are moving it


def test_the_pair_says_so_in_its_summary(tmp_path: Path) -> None:
    """Through the nodes: the hand held where it starts (on its path from the first state), the wrist in the
    dynamically consistent null space runs away, and the controller's warning reaches summary.json."""
    shared, sim, own = wrist_params(tmp_path, {"null_space": "dynamically_consistent", "hand.trajectory.type": "hold"})
    sets = [f"--set={key}={json.dumps(value)}" for key, value in {**shared, **sim, **own}.items()]
    output = tmp_path / "run"
    done = run(pair_argv(output, "--duration", "0.25", "--no-animation", *sets), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    warnings = json.loads((output / "summary.json").read_text())["warnings"]
    assert any("no task sees them" in w and "null_space_posture.kd" in w for w in warnings), warnings
