"""A controller a lab would run: integral action on the tasks (anti-windup, no kick), gains in acceleration
units that fit any arm, and per-joint torque limits (a list, or the URDF's efforts) with each joint's fraction
of steps at its limit in summary.json. In process (bracing_core.rollout: the engine the nodes run)."""

from __future__ import annotations

import itertools
import json
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import CONFIG_DIR, build_scenario
from ros_helpers import PAPER_YAML, pair_argv, run

from bracing_core import rollout
from bracing_core.params import ConfigError
from bracing_core.rollout import RunResult, run_recorded
from bracing_experiments.experiment import execute_run, summarize
from bracing_experiments.sweep import build_specs

TORQUE = {"input_mode": "torque"}
HELD = {"gravity_compensation": True}
# The integral gains the docs recommend for the paper arm's stiffness gains (hand kp 300 N/m, kd 50 N s/m;
# elbow kp 100 N/m, kd 20 N s/m): hand ki = kp / 0.3 s, the elbow's low (an integral against Coulomb friction
# hunts: elbow ki 300 stick-slips about its target, 2-3 mm)
HAND_KI = [1000.0, 1000.0]  # [N/(m s)]
ELBOW_KI = [100.0]  # [N/(m s)]
SEGMENT_S = 1.0  # the waypoint's move [s]


def hand_start(config: str = "paper_4link.yaml", sim: dict[str, Any] | None = None) -> np.ndarray:
    """The hand's first position (the law's kinematics at the start posture) [m]."""
    scenario = rollout.build_scenario(CONFIG_DIR / config, TORQUE, sim=sim, ctl=HELD)
    assert scenario.controller is not None
    return np.asarray(scenario.controller.engine.task_positions(scenario.sim.position)[0])


def moved_hand(target: np.ndarray, gains: dict[str, Any], duration: float = 8.0) -> RunResult:
    """The paper arm, torque input with gravity compensation, its hand moved to ``target`` by a waypoint."""
    ctl = {
        **HELD,
        "hand.trajectory.type": "waypoints",
        "hand.trajectory.waypoints": target.tolist(),
        "hand.trajectory.segment_time": SEGMENT_S,
        **gains,
    }
    return run_recorded(build_scenario(TORQUE, ctl=ctl), duration)


# -- integral action ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("direction", [(0.0, 1.0, 0.0), (0.0, 0.0, -1.0)])
def test_integral_action_holds_the_hand_on_a_target_3_cm_away(direction: tuple[float, ...]) -> None:
    """Moved 3 cm by a waypoint and held: PD leaves the hand ~31 mm off for good (the sliding elbow's friction
    and the gravity the paper's null space passes on are steady loads); with the integral gains within 1 mm
    from 3 s after the target arrives (measured 0.08 mm)."""
    target = hand_start() + 0.03 * np.array(direction)
    late = lambda rec: rec.time >= SEGMENT_S + 3.0  # noqa: E731
    pd = moved_hand(target, {})
    pid = moved_hand(target, {"hand.ki": HAND_KI, "contacts.elbow.ki": ELBOW_KI})
    pd_error = np.linalg.norm(pd.hand_actual - target, axis=1)[late(pd)]
    pid_error = np.linalg.norm(pid.hand_actual - target, axis=1)[late(pid)]
    assert pd_error.min() > 0.010
    assert pid_error.max() < 1e-3
    # and the elbow is back on its own target too (it slid ~60 mm while the hand moved)
    brace = np.abs(pid.brace_actual[:, 0] - pid.brace_desired[:, 0]).max(axis=1)[late(pid)]
    assert brace.max() < 1e-3


def test_integral_action_holds_the_hand_in_voltage_mode() -> None:
    """Voltage input (the paper's motors, their circuit a 0.28 s lag inside the loop): PD stays 27 mm off; the
    integral gains a third of torque input's (hand 300, elbow 30 N/(m s)) bring the hand within 1 mm from 3 s
    after the target arrives (measured 0.84 mm; with torque input's gains 2 mm)."""
    target = hand_start() + np.array([0.0, 0.03, 0.0])
    ctl = {
        **HELD,
        "hand.trajectory.type": "waypoints",
        "hand.trajectory.waypoints": target.tolist(),
        "hand.trajectory.segment_time": SEGMENT_S,
    }
    pd = run_recorded(build_scenario(ctl=ctl), 8.0)
    pid = run_recorded(build_scenario(ctl={**ctl, "hand.ki": [300.0, 300.0], "contacts.elbow.ki": [30.0]}), 8.0)
    late = pid.time >= SEGMENT_S + 3.0
    assert np.linalg.norm(pd.hand_actual - target, axis=1)[late].min() > 0.010
    assert np.linalg.norm(pid.hand_actual - target, axis=1)[late].max() < 1e-3


def _stepped(ctl: dict[str, Any], limit: float, steps: int) -> list[tuple[float, np.ndarray, np.ndarray, bool]]:
    """The paper arm's loop stepped by hand in torque mode with every |tau| saturated to ``limit``: per update
    (t, the hand's position error, its integral after the update, whether its command saturated)."""
    scenario = build_scenario({**TORQUE, "motors.torque_limit": limit}, ctl=ctl)
    controller, sim = scenario.controller, scenario.sim
    assert controller is not None
    out = []
    for _ in range(steps):
        answer = controller.update(sim.time, sim.position, sim.velocity)
        error = answer.hand_desired - answer.hand_actual
        saturated = bool(np.any(np.abs(answer.command) >= limit))
        out.append((sim.time, error, np.asarray(controller.engine.task_integral(0)), saturated))
        sim.step(np.clip(answer.command, -limit, limit))
    return out


def test_the_integral_holds_while_a_command_saturates() -> None:
    """Anti-windup, hand-checked: with a tight torque limit (15 N m: the commands reach it at the start and
    from 0.2 s, not between) the hand's integral grows by e dt at an update whose previous command was inside
    the limit, and not at all after one that saturated."""
    updates = _stepped({**HELD, "hand.ki": HAND_KI}, 15.0, 600)
    held = grew = 0
    for (_, _, before, saturated), (t, error, after, _) in itertools.pairwise(updates):
        expected = before if saturated else before + error * 1e-3
        expected[0] = 0.0  # x: no hand axis, no integral
        assert after == pytest.approx(expected, abs=1e-15), t
        held += saturated
        grew += not saturated
    assert held > 10 and grew > 10  # both branches were taken


def test_a_saturating_command_does_not_wind_the_integral_up() -> None:
    """Every command at a 1e-3 N m limit: the integral stays exactly zero, while without the limit it grows."""
    saturated = _stepped({**HELD, "hand.ki": HAND_KI}, 1e-3, 200)
    assert all(s for *_, s in saturated)
    assert all(not np.any(integral) for _, _, integral, _ in saturated)
    free = _stepped({**HELD, "hand.ki": HAND_KI}, 1e6, 200)
    assert np.any(free[-1][2] != 0.0)


def test_integral_gains_are_tunable_and_reset_forgets_the_integral() -> None:
    """hand.ki set while running starts from a zero integral (no kick: the first command differs from the PD
    one by ki e dt alone); set to zero it forgets it; reset() clears it."""
    scenario = build_scenario(TORQUE, ctl=HELD)
    controller, sim = scenario.controller, scenario.sim
    assert controller is not None
    for _ in range(50):
        sim.step(controller.update(sim.time, sim.position, sim.velocity).command)
    assert not np.any(controller.engine.task_integral(0))
    config = controller.config
    controller.retune(replace(config, hand_task=replace(config.hand_task, ki=(1000.0, 1000.0))))
    answer = controller.update(sim.time, sim.position, sim.velocity)
    error = answer.hand_desired - answer.hand_actual
    assert controller.engine.task_integral(0)[1:] == pytest.approx(error[1:] * 1e-3, abs=1e-15)
    controller.retune(replace(config, hand_task=replace(config.hand_task, ki=(1000.0, 0.0))))
    controller.update(sim.time + 1e-3, sim.position, sim.velocity)
    assert controller.engine.task_integral(0)[2] == 0.0 and controller.engine.task_integral(0)[1] != 0.0
    controller.reset()
    assert not np.any(controller.engine.task_integral(0))


def test_integral_gains_need_one_per_axis() -> None:
    with pytest.raises(ConfigError, match=r"hand\.ki: expected 2 values .*or an empty list"):
        build_scenario(TORQUE, ctl={"hand.ki": [1.0]})
    with pytest.raises(ConfigError, match=r"contacts\.elbow\.ki: values must be >= 0"):
        build_scenario(TORQUE, ctl={"contacts.elbow.ki": [-1.0]})


# -- gains in acceleration units ---------------------------------------------------------------------------------
BANDWIDTH_RAD_S = 2.0 * np.pi * 2.0  # the hand's and the braces' (critically damped: kp = w^2, kd = 2 w)
ACCELERATION = {"gains": "acceleration"}


def _acceleration_gains(config: str) -> dict[str, Any]:
    kp, kd = BANDWIDTH_RAD_S**2, 2.0 * BANDWIDTH_RAD_S
    if config == "ur5_table.yaml":  # three hand axes, roll and heading held, no brace axes; PD alone, no start ramp
        pd = {"hand.kp": [kp] * 3, "hand.kd": [kd] * 3}
        pd |= {"hand.orientation.kp": [kp] * 2, "hand.orientation.kd": [kd] * 2}
        no_integral = {"hand.ki": [], "hand.orientation.ki": [], "hand.trajectory.start_ramp": 0.0}
        return {**ACCELERATION, **pd, **no_integral}
    braces = {"paper_4link.yaml": ["elbow"], "wall_7link.yaml": ["elbow1", "elbow2"]}[config]
    gains: dict[str, Any] = {**ACCELERATION, "hand.kp": [kp, kp], "hand.kd": [kd, kd]}
    for brace in braces:
        gains |= {f"contacts.{brace}.kp": [kp], f"contacts.{brace}.kd": [kd]}
    return gains


def step_response(config: str, gains: dict[str, Any], step: np.ndarray, duration: float = 2.0) -> np.ndarray:
    """The hand's response to a held target ``step`` away (torque input, gravity compensated), as a fraction of
    the step: the run with the step less the run without (the loads both share cancel), along the step."""
    start = hand_start(config)
    hand = []
    for offset in (np.zeros(3), step):
        ctl = {**HELD, "hand.trajectory.type": "hold", "hand.trajectory.point": (start + offset).tolist(), **gains}
        recording = run_recorded(rollout.build_scenario(CONFIG_DIR / config, TORQUE, ctl=ctl), duration)
        hand.append(recording.hand_actual)
    return np.asarray((hand[1] - hand[0]) @ step / float(step @ step))


def rise_time(response: np.ndarray, step_s: float = 1e-3) -> float:
    """10 % to 90 % of the final value [s]."""
    final = response[-1]
    return float((np.argmax(response >= 0.9 * final) - np.argmax(response >= 0.1 * final)) * step_s)


@pytest.mark.parametrize("axis", [1, 2])
def test_acceleration_gains_give_the_same_rise_time_on_three_arms(axis: int) -> None:
    """The same acceleration gains (2 Hz, critically damped: a 10-90 % rise of 3.36 / w = 0.27 s) on the paper
    arm, on the 7-link arm braced on a floor and a wall and on the shipped UR5 (geared servos, its wrist on a
    table, its tool's roll and heading held): rise times within 10 % of each other (measured: 0.265-0.266 s on
    each); with the paper's stiffness gains they are not (the same 300 N/m on different inertias)."""
    step = np.zeros(3)
    step[axis] = 0.01
    configs = ("paper_4link.yaml", "wall_7link.yaml", "ur5_table.yaml")
    rises = {c: rise_time(step_response(c, _acceleration_gains(c), step)) for c in configs}
    assert max(rises.values()) - min(rises.values()) <= 0.1 * min(rises.values()), rises
    assert rises["paper_4link.yaml"] == pytest.approx(3.358 / BANDWIDTH_RAD_S, rel=0.25)


def test_acceleration_gains_set_the_tasks_accelerations() -> None:
    """At the start (at rest), the hand's acceleration answers a target step as kp times the step, whatever the
    arm: the difference of the simulated accelerations with and without the step (the rest of l cancels)."""
    kp = BANDWIDTH_RAD_S**2
    for config in ("paper_4link.yaml", "wall_7link.yaml"):
        start = hand_start(config)
        accelerations = []
        for offset in (np.zeros(3), np.array([0.0, 0.01, 0.0])):
            ctl = {**HELD, "hand.trajectory.type": "hold", "hand.trajectory.point": (start + offset).tolist()}
            scenario = rollout.build_scenario(CONFIG_DIR / config, TORQUE, ctl={**ctl, **_acceleration_gains(config)})
            assert scenario.controller is not None
            sim, robot = scenario.sim, scenario.plant.robot
            answer = scenario.controller.update(0.0, sim.position, sim.velocity)
            robot.compute(sim.position, sim.velocity)
            jacobian = robot.frame_jacobian(robot.frame_id("hand"))
            accelerations.append(jacobian @ sim.evaluate(answer.command).acceleration)
        assert accelerations[1] - accelerations[0] == pytest.approx([0.0, 0.01 * kp, 0.0], abs=0.02 * 0.01 * kp)


def test_gains_must_be_a_known_kind() -> None:
    with pytest.raises(ConfigError, match="gains"):
        build_scenario(TORQUE, ctl={"gains": "impedance"})


# -- per-joint torque limits -------------------------------------------------------------------------------------
def test_a_torque_limit_per_joint_saturates_each_joint_at_its_own() -> None:
    """motors.torque_limit as a list: each joint's command saturated to its own value, in the in-process loop as
    in the simulator node (the same states as a loop stepped by hand with numpy's clip)."""
    limits = [20.0, 5.0, 2.0, 1.0]  # robot.joint_names order (the paper's is the model order)
    shared = {**TORQUE, "motors.torque_limit": limits}
    scenario = build_scenario(shared, ctl=HELD)
    assert scenario.plant.command_limit.tolist() == limits
    recording = run_recorded(scenario, 0.3)
    assert np.any(np.abs(recording.command) > limits)  # the law asked for more
    by_hand = build_scenario(shared, ctl=HELD)
    assert by_hand.controller is not None
    for _ in range(300):
        answer = by_hand.controller.update(by_hand.sim.time, by_hand.sim.position, by_hand.sim.velocity)
        by_hand.sim.step(np.clip(answer.command, -np.array(limits), limits))
    np.testing.assert_array_equal(by_hand.sim.position, recording.position[-1])


def test_one_torque_limit_is_every_joints_and_a_wrong_count_is_refused() -> None:
    assert build_scenario({**TORQUE, "motors.torque_limit": 7.0}).plant.command_limit.tolist() == [7.0] * 4
    with pytest.raises(ConfigError, match=r"motors\.torque_limit: expected one value or 4"):
        build_scenario({**TORQUE, "motors.torque_limit": [1.0, 2.0]})
    with pytest.raises(ConfigError, match=r"motors\.torque_limit: values must be >= 0"):
        build_scenario({**TORQUE, "motors.torque_limit": [1.0, -2.0, 1.0, 1.0]})


def test_torque_limits_from_the_urdf() -> None:
    """motors.torque_limit_from_urdf: each joint's <limit effort>, read from the URDF by name (the 7-link arm's
    run from 75 N m at the shoulder to 5 N m at the wrist), whatever motors.torque_limit says."""
    efforts = {
        joint.get("name"): float(joint.find("limit").get("effort"))  # type: ignore[union-attr]
        for joint in ET.parse(CONFIG_DIR / "hyper_7link.urdf").getroot().iter("joint")
        if joint.find("limit") is not None
    }
    scenario = rollout.build_scenario(
        CONFIG_DIR / "wall_7link.yaml",
        {**TORQUE, "motors.torque_limit_from_urdf": True, "motors.torque_limit": 1.0},
        ctl={**HELD},
    )
    limits = dict(zip(scenario.plant.joint_names, scenario.plant.command_limit.tolist(), strict=True))
    assert limits == {name: efforts[name] for name in scenario.plant.joint_names}
    assert len(set(limits.values())) > 3
    assert scenario.controller is not None  # the law's anti-windup reads the same limits
    assert scenario.controller.plant.command_limit.tolist() == scenario.plant.command_limit.tolist()


def test_saturation_fraction_in_the_summary_hand_checked() -> None:
    """summary.json's saturation_fraction: per joint, the fraction of the controller's commands at or beyond
    its limit (0 for a joint without one), counted here by hand; null without any limit."""
    limits = np.array([0.0, 0.0, 3.0, 0.5])
    recording = run_recorded(build_scenario({**TORQUE, "motors.torque_limit": limits.tolist()}, ctl=HELD), 1.0)
    summary = summarize(recording, 1.0)
    by_hand = {
        name: float(np.mean(np.abs(recording.command[:, j]) >= limits[j])) if limits[j] > 0 else 0.0
        for j, name in enumerate(recording.joint_names)
    }
    assert summary["saturation_fraction"] == by_hand
    assert 0.0 < by_hand["joint3"] < 1.0 and by_hand["joint4"] > 0.0
    assert summarize(run_recorded(build_scenario(TORQUE, ctl=HELD), 0.1), 0.1)["saturation_fraction"] is None


def _recommended(config: str) -> dict[str, Any]:
    """The guide's starting gains: each axis's PID poles at -w (kd 3 w, kp 3 w^2, ki w^3), the hand at 2 Hz, the
    braces at 1 Hz with a tenth of that ki."""
    hand, brace = 2.0 * np.pi * 2.0, 2.0 * np.pi * 1.0
    gains: dict[str, Any] = {
        **HELD,
        **ACCELERATION,
        "hand.kp": [3 * hand**2] * 2,
        "hand.kd": [3 * hand] * 2,
        "hand.ki": [hand**3] * 2,
    }
    for name in {"paper_4link.yaml": ["elbow"], "wall_7link.yaml": ["elbow1", "elbow2"]}[config]:
        gains |= {
            f"contacts.{name}.kp": [3 * brace**2],
            f"contacts.{name}.kd": [3 * brace],
            f"contacts.{name}.ki": [brace**3 / 10],
        }
    return gains


@pytest.mark.parametrize(
    ("config", "shared", "bound_m"),
    [
        ("paper_4link.yaml", TORQUE, 0.5e-3),  # measured 0.13 mm (its stiffness gains: 22.8 mm)
        ("wall_7link.yaml", TORQUE, 0.2e-3),  # 0.02 mm (5.9 mm)
        # a circuit much faster than the arm (L / R = 1.7 ms), the motor inverted: 0.18 mm (16 mm)
        ("paper_4link.yaml", {"motors.inductance": [1e-3] * 4}, 0.5e-3),
    ],
)
def test_the_recommended_gains_track_the_circle(config: str, shared: dict[str, Any], bound_m: float) -> None:
    """The guide's recommended acceleration gains on the 10 s circle: the hand's RMS error after 2 s."""
    ctl = {**_recommended(config), "voltage_law.back_emf_compensation": True}
    recording = run_recorded(rollout.build_scenario(CONFIG_DIR / config, shared, ctl=ctl), 10.0)
    error = np.linalg.norm(recording.hand_actual - recording.hand_desired, axis=1)[recording.time >= 2.0]
    assert float(np.sqrt(np.mean(error**2))) < bound_m


def test_the_pairs_saturation_fraction_is_the_in_process_runs(tmp_path: Path) -> None:
    """Over DDS: bracing-pair with a torque limit per joint; the recorder notes the limits in the bag, the
    report reads the bag's motor_command, and summary.json's saturation_fraction is the in-process run's."""
    sets = ("input_mode=torque", "gravity_compensation=true", "motors.torque_limit=[20.0, 5.0, 2.0, 1.0]")
    out = tmp_path / "limits"
    done = run(
        pair_argv(out, "--duration", "0.3", "--no-animation", *(a for s in sets for a in ("--set", s))), timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    pair = json.loads((out / "summary.json").read_text())["saturation_fraction"]
    (spec,) = build_specs(PAPER_YAML, list(sets), zipped=False, duration=0.3)
    in_process = execute_run(spec).summary
    assert in_process is not None
    assert pair == in_process["saturation_fraction"]
    assert 0.0 < min(pair.values()) and max(pair.values()) < 1.0


# -- the hand's orientation ------------------------------------------------------------------------------------
def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix about the unit ``axis`` by ``angle`` [rad]."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


def _quaternion(rotation: np.ndarray) -> list[float]:
    """[x, y, z, w] of a rotation matrix (w > 0 here: rotations under pi)."""
    w = 0.5 * np.sqrt(1.0 + np.trace(rotation))
    x = (rotation[2, 1] - rotation[1, 2]) / (4.0 * w)
    y = (rotation[0, 2] - rotation[2, 0]) / (4.0 * w)
    z = (rotation[1, 0] - rotation[0, 1]) / (4.0 * w)
    return [float(x), float(y), float(z), float(w)]


PAPER = "paper_4link.yaml"
# the paper arm turning its hand as well: three task rows (hand y, z; a turn about x) fill its n - p = 3, so the
# elbow keeps its force but no position task of its own
NO_BRACE_TASK = {"contacts.elbow.brace_axes": [], "contacts.elbow.kp": [], "contacts.elbow.kd": []}
# and from a posture where it can: at the paper's (q3 = 0.8 pi) the hand's y, z and turn have rank 2 beside the
# elbow's contact; 0.1 rad less at the third joint (the elbow, on links 1-2, stays where it was) has rank 3
TURNABLE = {"initial_position": [-0.2 * np.pi, -0.6 * np.pi, 0.8 * np.pi - 0.1, -0.4 * np.pi]}


def _hand_rotation(config: str, sim: dict[str, Any] | None = None) -> np.ndarray:
    scenario = rollout.build_scenario(CONFIG_DIR / config, TORQUE, sim=sim, ctl=HELD)
    robot = scenario.plant.robot
    robot.compute(scenario.sim.position, scenario.sim.velocity)
    return np.asarray(robot.data.oMf[robot.frame_id("hand")].rotation)


def test_the_orientation_error_is_the_log_map_in_world_axes() -> None:
    """A target turned from the hand's start by 0.4 rad about a tilted world axis u: the law's error at the start
    is 0.4 u (log(R_d R^T) = log(Rot(u, 0.4))), hand-computed with Rodrigues' formula."""
    start = _hand_rotation(PAPER, TURNABLE)
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    target = _rotation(axis, 0.4) @ start
    ctl = {**HELD, **NO_BRACE_TASK, "hand.orientation.axes": ["x"], "hand.orientation.kp": [1.0]}
    ctl |= {"hand.orientation.kd": [0.1], "hand.orientation.target": _quaternion(target)}
    scenario = build_scenario(TORQUE, sim=TURNABLE, ctl=ctl)
    assert scenario.controller is not None
    answer = scenario.controller.update(0.0, scenario.sim.position, scenario.sim.velocity)
    assert answer.orientation_error == pytest.approx(0.4 * axis, abs=1e-12)


def test_a_held_orientation_is_reached_with_the_position() -> None:
    """The paper arm, torque input, acceleration gains (hand and turn at 1 Hz, poles at -w), its hand held 1 cm
    away and turned 0.05 rad about x (the plane's normal): within 1 mm and 5 mrad from 3 s on; summary.json's
    hand_orientation_rms_error_rad (null without the task)."""
    start = hand_start(PAPER, TURNABLE)
    turn = _rotation(np.array([1.0, 0.0, 0.0]), 0.05) @ _hand_rotation(PAPER, TURNABLE)
    w = 2.0 * np.pi * 1.0
    ctl = {
        **HELD,
        **ACCELERATION,
        **NO_BRACE_TASK,
        "hand.kp": [3 * w**2] * 2,
        "hand.kd": [3 * w] * 2,
        "hand.ki": [w**3] * 2,
        "hand.trajectory.type": "hold",
        "hand.trajectory.point": (start + np.array([0.0, 0.01, 0.0])).tolist(),
        "hand.orientation.axes": ["x"],
        "hand.orientation.kp": [3 * w**2],
        "hand.orientation.kd": [3 * w],
        "hand.orientation.ki": [w**3],
        "hand.orientation.target": _quaternion(turn),
    }
    recording = run_recorded(build_scenario(TORQUE, sim=TURNABLE, ctl=ctl), 5.0)
    late = recording.time >= 3.0
    assert np.linalg.norm(recording.hand_actual - recording.hand_desired, axis=1)[late].max() < 1e-3
    assert np.linalg.norm(recording.hand_orientation_error, axis=1)[late].max() < 5e-3
    assert np.linalg.norm(recording.hand_orientation_error[0]) == pytest.approx(0.05, abs=1e-12)
    summary = summarize(recording, 1.0)
    assert 0.0 < summary["hand_orientation_rms_error_rad"] < 5e-3
    plain = summarize(run_recorded(build_scenario(TORQUE, ctl=HELD), 2.1), 1.0)
    assert plain["hand_orientation_rms_error_rad"] is None


def test_the_rank_check_counts_the_orientation_rows() -> None:
    """A planar arm cannot turn its hand about y; orientation rows count in the task dimension; a quaternion
    of norm 0 is refused."""
    turn = {**NO_BRACE_TASK, "hand.orientation.kp": [1.0], "hand.orientation.kd": [0.1]}
    with pytest.raises(ConfigError, match=r"hand\.orientation\.axes: frame 'hand' cannot rotate about y at the start"):
        build_scenario(TORQUE, ctl={**turn, "hand.orientation.axes": ["y"]})
    brace = {"hand.orientation.axes": ["x"], "hand.orientation.kp": [1.0], "hand.orientation.kd": [0.1]}
    with pytest.raises(ConfigError, match=r"task dimension 4 \(hand 2 \+ orientation 1 \+ brace 1\) exceeds n - p"):
        build_scenario(TORQUE, ctl=brace)
    with pytest.raises(ConfigError, match=r"\[x\] with hand\.axes \[y, z\] needs 3 free directions .* the arm has 2"):
        build_scenario(TORQUE, ctl={**turn, "hand.orientation.axes": ["x"]})  # the paper's posture
    assert build_scenario(TORQUE, sim=TURNABLE, ctl={**turn, "hand.orientation.axes": ["x"]}).controller is not None
    with pytest.raises(ConfigError, match=r"hand\.orientation\.target: a quaternion"):
        build_scenario(
            TORQUE, sim=TURNABLE, ctl={**turn, "hand.orientation.axes": ["x"], "hand.orientation.target": [0.0] * 4}
        )
