"""The shipped published arm (config/ur5_table.yaml): example-robot-data's UR5, unmodified, on geared
servos (gear 100, K 0.1 N m/A, R 0.5 ohm, L 0.1 mH), its wrist_1_link leaning 10 N on a table while
the tool point draws a circle of radius 3 cm parallel to the table, its roll and heading held, with
gains in acceleration units at the recommended bandwidths.

The targets are measured on one turn (5 s) of the in-process rollout, the engine the pair runs; one
short run of the pair shows that the nodes run the file end to end as the rollout does. It is not in
test_scenarios.py's list: there torque input must hold f_n = f_nd to 1e-9 at every step, and here the
wrist breaking free of the table (Coulomb stick, then slip, at t = 0.543 s) takes f_n to 11.6 N for a
moment (eq. 40 assumes the contact slides); the oracle (test_oracle.py) checks its plant step by step.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIG_DIR
from ros_helpers import bag_joint_positions, pair_argv, run

from bracing_core.meshes import find_package, mesh_uris, resolved_description
from bracing_core.params import ConfigError, resolve_file
from bracing_core.rcl_yaml import load_params_file
from bracing_core.rollout import RunResult, build_scenario, run_recorded

UR5 = CONFIG_DIR / "ur5_table.yaml"
TURN_S = 5.0  # one turn of the circle (hand.trajectory.period)
F_ND = 10.0  # [N], contacts.wrist.desired_normal_force
SETTLED_S = 2.0  # summary.json's window for the hand's errors (bracing_analysis.summary.HAND_ERROR_T_MIN_S)


def ur5(mode: str, sim: dict[str, object] | None = None, ctl: dict[str, object] | None = None) -> RunResult:
    scenario = build_scenario(UR5, shared={"input_mode": mode}, sim=sim, ctl=ctl)
    return run_recorded(scenario, TURN_S)


def hand_rms_m(rec: RunResult, since: float = 0.0) -> float:
    window = rec.time >= since - 1e-9
    return float(np.sqrt(np.mean(np.sum((rec.hand_desired[window] - rec.hand_actual[window]) ** 2, axis=1))))


def orientation_rms_rad(rec: RunResult, since: float = 0.0) -> float:
    """|log(R_d R^T)| over every axis, the free pitch included (as summary.json's)."""
    window = rec.time >= since - 1e-9
    return float(np.sqrt(np.mean(np.sum(rec.hand_orientation_error[window] ** 2, axis=1))))


@pytest.fixture(scope="module")
def torque() -> RunResult:
    return ur5("torque")


@pytest.fixture(scope="module")
def voltage() -> RunResult:
    return ur5("voltage")


def test_the_arm_is_example_robot_datas_own() -> None:
    """The URDF and every mesh are the installed package's files (no copy in the repository), and the
    torque limits are the URDF's <limit effort>: 150 N m on shoulder and elbow, 28 N m on the wrist."""
    urdf_name = load_params_file(UR5, "bracing_simulator")["robot.urdf"]
    assert urdf_name == "package://example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
    package = find_package("example-robot-data")
    assert package is not None, "example-robot-data (requirements) is not installed"
    scenario = build_scenario(UR5, shared={"input_mode": "torque"}, with_controller=False)
    assert scenario.sim_config is not None
    urdf = scenario.sim_config.shared.urdf
    assert urdf == (package / "robots/ur_description/urdf/ur5_robot.urdf").resolve()
    text = urdf.read_text()
    assert len(mesh_uris(text)) == 14  # 7 links, a visual and a collision mesh each
    _, missing = resolved_description(text)
    assert missing == []
    assert not list(CONFIG_DIR.glob("ur5*.urdf"))
    np.testing.assert_array_equal(scenario.plant.motors.torque_limit, [150.0, 150.0, 150.0, 28.0, 28.0, 28.0])


def test_a_package_urdf_that_is_not_installed_is_refused_saying_where_it_was_looked_for() -> None:
    with pytest.raises(ConfigError, match=r"robot.urdf: 'package://no_such_robots/a.urdf' not found .*cmeel prefix"):
        resolve_file("package://no_such_robots/a.urdf", "robot.urdf")
    with pytest.raises(ConfigError, match="not found"):  # the package is there, the file is not
        resolve_file("package://example-robot-data/robots/none.urdf", "robot.urdf")


def test_torque_input_tracks_the_circle_and_holds_the_tool(torque: RunResult) -> None:
    """Issue target: hand RMS <= 3 mm, orientation RMS <= 5 mrad, here over the whole turn (the start
    included). Measured: 2.47 mm and 2.16 mrad over the turn, 0.03 mm and 0.54 mrad from 2 s. The start
    is the largest part: the wrist sticks on the table (Coulomb, mu 0.3) for ~0.6 s, the law models no
    friction, and the hand lags up to 10.9 mm until it slides; with the friction regularised it does not
    (0.06 mm). After 2 s (summary.json's window) the errors are 100 times below the targets."""
    assert rec_is_full(torque)
    assert hand_rms_m(torque) <= 3e-3
    assert orientation_rms_rad(torque) <= 5e-3
    assert hand_rms_m(torque, SETTLED_S) <= 1e-4  # measured 0.030 mm
    assert orientation_rms_rad(torque, SETTLED_S) <= 1e-3  # measured 0.54 mrad, the free pitch's offset
    held = torque.hand_orientation_error[:, [0, 2]]  # roll and heading, the held axes
    assert float(np.max(np.abs(held[torque.time >= SETTLED_S]))) <= 1e-4
    assert np.all(torque.active[:, 0])
    center = load_params_file(UR5, "bracing_controller")["hand.trajectory.center"]
    circle = torque.hand_desired[torque.time >= 1.0] - np.asarray(center)  # past the start ramp
    np.testing.assert_allclose(np.linalg.norm(circle[:, :2], axis=1), 0.03, rtol=0, atol=1e-12)
    np.testing.assert_allclose(circle[:, 2], 0.0, rtol=0, atol=1e-12)  # parallel to the table
    limits = np.array([150.0, 150.0, 150.0, 28.0, 28.0, 28.0])
    assert np.all(np.abs(torque.command) <= limits + 1e-9)


def rec_is_full(rec: RunResult) -> bool:
    return bool(rec.time[-1] == pytest.approx(TURN_S))


def force_figures(rec: RunResult) -> tuple[float, float, float]:
    """(max f_n [N], fraction of steps in contact, f_n's RMS error [N]) of the wrist over the run."""
    f_n = rec.normal_force[:, 0]
    return float(np.max(f_n)), float(np.mean(rec.active[:, 0])), float(np.sqrt(np.mean((f_n - F_ND) ** 2)))


def test_voltage_input_with_the_recommended_settings_keeps_its_brace(voltage: RunResult) -> None:
    """Issue target, voltage input with the file's settings (initial_current steady, start_ramp 0.5 s,
    back-EMF compensation, force feedback kp 0.3, ki 100 /s from checks.force_feedback_gains(0.2 ms, 1 ms)):
    f_n never above 1.5 f_nd, the contact active >= 99 % of the run, force RMS <= 1 N. Measured: 10.1 N
    at most, 100 %, 0.005 N; the hand 0.07 mm RMS over the turn."""
    assert rec_is_full(voltage)
    peak, active, rms = force_figures(voltage)
    assert peak <= 1.5 * F_ND
    assert active >= 0.99
    assert rms <= 1.0
    assert hand_rms_m(voltage) <= 3e-3
    assert orientation_rms_rad(voltage) <= 5e-3


def test_without_the_recommended_settings_voltage_input_kicks_and_chatters() -> None:
    """What the settings prevent (the targets above can fail): the windings from 0 A and a reference that
    starts moving push 54 N on the 10 N brace in the first steps; the docs' former force feedback (kp 1,
    ki 10 /s) on top lets the wrist off the table (force RMS 2.65 N)."""
    abrupt = {"hand.trajectory.start_ramp": 0.0}
    cold = {"initial_current": "zero"}
    kicked = ur5("voltage", sim=cold, ctl=abrupt)
    assert force_figures(kicked)[0] > 3.0 * F_ND  # measured 54.4 N
    former = {"contacts.wrist.force_feedback.kp": 1.0, "contacts.wrist.force_feedback.ki": 10.0}
    scenario = build_scenario(UR5, shared={"input_mode": "voltage", **former}, sim=cold, ctl=abrupt)
    chattered = run_recorded(scenario, TURN_S)
    _, active, rms = force_figures(chattered)
    assert active < 1.0 and float(np.min(chattered.normal_force[:, 0])) == 0.0  # it let go
    assert rms > 1.0  # measured 2.65 N


def test_the_pair_runs_it_as_the_in_process_loop(tmp_path: Path) -> None:
    """bracing-pair (separate processes over DDS, recorded) runs the torque scenario: the same trajectory
    as the rollout, every mesh found, and a summary.json with status ok."""
    seconds = 2.5
    output = tmp_path / "ur5"
    argv = pair_argv(output, "--duration", str(seconds), "--no-animation", config=UR5)
    done = run(argv, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    positions = bag_joint_positions(output / "bag")
    reference = run_recorded(build_scenario(UR5), seconds)
    np.testing.assert_array_equal(positions, reference.position)  # bit for bit, 2.5 s
    summary = json.loads((output / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["error"] is None
    assert summary["hand_rms_error_m"] <= 1e-4  # from 2 s: measured 0.03 mm
    assert summary["contacts"]["wrist"]["active_fraction"] == 1.0
    assert not [w for w in summary["warnings"] if "mesh" in w]
