"""Failures a user can act on: every run says its status; a failed one names what ran away and, for each
known cause, what to change (``bracing_core.failures``), in process as through the pair (summary.json, exit
3, the bag up to the failure, no watchdog wait).

The causes, one by one: a light wrist that no task sees running to its limit (the free wrist of
test_real_arm), a target out of reach (the paper arm's hand held 2.6 m out: in voltage input a winding
burns at 3.56 s), a singular posture (the paper arm stretched), a stiff circuit (a gear-100 servo stepped
without its sub-steps), a contact lost under force feedback (a unilateral elbow with fast force gains).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from conftest import build_scenario
from ros_helpers import pair_argv, run
from test_real_arm import geared, wrist_params

from bracing_analysis.bag import read_series
from bracing_analysis.report import write_report
from bracing_analysis.series import BagSeries
from bracing_analysis.summary import compute_summary
from bracing_core.failures import FAILED, OK, History, diagnose, stiff_circuit
from bracing_core.rollout import RunResult, run_recorded

FAR = {"hand.trajectory.type": "hold", "hand.trajectory.point": [0.0, 2.6, 0.6]}  # the arm reaches 2.0 m


def wrist_run(tmp_path: Path, ctl: dict[str, object], duration: float = 1.0) -> RunResult:
    shared, sim, own = wrist_params(tmp_path, ctl)
    return run_recorded(build_scenario(shared, sim=sim, ctl=own), duration, keep_failure=True)


def test_a_wrist_at_its_limit_with_an_undamped_null_space_names_it_and_hints_the_posture_task(tmp_path: Path) -> None:
    """The wrist spins to its limit in 0.062 s: the recording stops there, the error names the wrist and how
    fast it grew, the hint names null_space_posture; with the posture task the same arm runs to its end."""
    failed = wrist_run(tmp_path, {})
    assert failed.status == FAILED and failed.error is not None and failed.hint is not None
    assert "joint 'wrist' would leave its URDF limits" in failed.error
    assert "ran away: wrist (" in failed.error  # the only joint that grew
    assert "null_space_posture.kd" in failed.hint
    assert failed.time[-1] < 0.1 and np.all(np.isfinite(failed.position))  # every state up to the failure
    posture = {"null_space_posture.kp": [0.0] * 4 + [1.0], "null_space_posture.kd": [0.0] * 4 + [0.2]}
    held = wrist_run(tmp_path, {"null_space": "dynamically_consistent", **posture})
    assert (held.status, held.error, held.hint) == (OK, None, None)


def test_a_target_out_of_reach_is_the_hint_of_the_run_it_ruins() -> None:
    """Held 2.6 m out, the hand drags the arm straight: in voltage input a winding burns (failed, the reach
    hint, the error naming the singular posture it died in); in torque input it runs on (ok, the same hint)."""
    burnt = run_recorded(build_scenario(ctl=FAR), 4.0, keep_failure=True)
    assert burnt.status == FAILED and burnt.error is not None and burnt.hint is not None
    assert "winding" in burnt.error and "near a singular posture" in burnt.error
    assert "out of reach" in burnt.hint
    stretched = run_recorded(build_scenario({"input_mode": "torque"}, ctl=FAR), 1.0, keep_failure=True)
    assert stretched.status == OK and stretched.error is None
    assert stretched.hint is not None and "out of reach" in stretched.hint


def _stopped_at(q: np.ndarray, shared: dict[str, object] | None = None, step: tuple[float, int] = (1e-3, 1)) -> object:
    scenario = build_scenario(shared)
    assert scenario.controller is not None
    times = np.arange(51) * 1e-3
    velocity = np.outer(np.exp(times / 0.01), [0.0, 1.0, -1.0, 0.5])  # joints 2-4 doubling every 7 ms
    history = History(times, np.tile(q, (51, 1)), velocity, scenario.plant.joint_names)
    reason = "non-finite state after the step at t = 0.050000 s; state kept"
    return diagnose(reason, history, scenario.plant, scenario.controller.config, step)


def test_a_singular_posture_is_named_with_the_joints_along_its_lost_direction() -> None:
    """The paper arm stretched out (joints 2-4 at 0): the hand's radial direction is lost; the error says so and
    names the joints that grew, the hint says how to keep away. At its start posture: no such word."""
    stretched = _stopped_at(np.array([-0.6, 0.0, 0.0, 0.0]))
    assert stretched.status == FAILED and stretched.cause == "singular"
    assert "near a singular posture" in stretched.error and "ran away: joint2" in stretched.error
    assert "damping_lambda" in stretched.hint
    start = build_scenario(with_controller=False).sim.position
    bent = _stopped_at(start)
    assert "singular" not in bent.error and bent.hint is None


def test_a_stiff_circuit_stepped_without_its_sub_steps_hints_them() -> None:
    """A gear-100 servo (L / R 0.2 ms, its electromechanical mode ~5000 1/s) stepped at 1 ms in one RK4 step
    is beyond RK4's stability: the hint gives the sub-steps the simulator needs (12, as it picks itself)."""
    servo = build_scenario(geared(), with_controller=False)
    q = servo.sim.position
    assert stiff_circuit(servo.plant, q, 1e-3, servo.sim.substeps) is None  # as the simulator steps it
    _, product, needed = stiff_circuit(servo.plant, q, 1e-3, 1) or (0.0, 0.0, 0)
    assert product > 2.78 and needed == servo.sim.substeps == 12
    failure = _stopped_at(q, geared())
    assert failure.cause == "stiff_circuit" and "substeps >= 12" in failure.hint
    assert _stopped_at(q, geared(), step=(1e-3, 12)).cause == ""  # sub-stepped: not this cause


def test_a_contact_lost_under_force_feedback_says_what_to_change() -> None:
    """A unilateral elbow on a geared arm with force gains faster than the arm (kp 5, ki 100 1/s) lets go at
    3 ms: the warning names its force_feedback gains and the ones derived for these motors (the circuit
    settles within a step: kp 0.3, ki 100 /s), the hint says to lower them; without feedback no hint."""
    shared = {**geared(), "contacts.elbow.unilateral": True}
    fast = {"contacts.elbow.force_feedback.kp": 5.0, "contacts.elbow.force_feedback.ki": 100.0}
    bemf = {"voltage_law.back_emf_compensation": True}
    lost = run_recorded(build_scenario({**shared, **fast}, ctl=bemf), 0.5, keep_failure=True)
    let_go = [w for w in lost.warnings if "let go" in w]
    assert (
        let_go and "contacts.elbow.force_feedback.kp and .ki (for these motors: kp <= 0.3, ki <= 100 /s)" in let_go[0]
    )
    assert lost.status == OK and lost.hint is not None and "contacts.elbow.force_feedback.kp" in lost.hint
    assert compute_summary(BagSeries(), warnings=let_go, fed_back=["elbow"])["hint"] == lost.hint  # as the pair says
    assert compute_summary(BagSeries(), warnings=let_go)["hint"] is None  # no force feedback: not this cause


def test_a_summary_without_a_failure_is_ok_without_error_or_hint() -> None:
    summary = compute_summary(BagSeries())
    assert (summary["status"], summary["error"], summary["hint"]) == (OK, None, None)


def test_the_pair_writes_the_failed_runs_summary_and_bag_up_to_the_divergence(tmp_path: Path) -> None:
    """Through the nodes: exit 3, summary.json failed with the error and the hint the in-process run gives,
    every state up to the failure in the bag (none lost in the simulator's last batch), and no watchdog wait
    (the simulator stops at the refused step: no watchdog warning)."""
    shared, sim, own = wrist_params(tmp_path, {})
    sets = [f"--set={key}={json.dumps(value)}" for key, value in {**shared, **sim, **own}.items()]
    output = tmp_path / "run"
    done = run(pair_argv(output, "--duration", "1.0", "--no-animation", *sets), timeout=300)
    assert done.returncode == 3, done.stdout + done.stderr
    assert "hint: " in done.stderr and "null_space_posture.kd" in done.stderr
    summary = json.loads((output / "summary.json").read_text())
    assert summary["status"] == FAILED and "ran away: wrist" in summary["error"]
    assert "joint 'wrist' would leave its URDF limits" in summary["error"]
    assert "null_space_posture.kd" in summary["hint"]
    assert not any("no valid motor_command" in w for w in summary["warnings"])
    series = read_series(output / "bag")
    failed_at = wrist_run(tmp_path, {}).time[-1]  # the in-process run's last state before the refused step
    assert series.joint_t[-1] >= failed_at - 1e-9  # the state the refused step started from is there
    assert series.topic_counts["/joint_states"] == round(series.joint_t[-1] / 1e-3) + 1  # and every one before
    assert summary["sim_time_s"] >= failed_at - 1e-9
    redrawn = write_report(output / "bag", animation_interval_s=None)  # bracing-report keeps why it failed
    assert (redrawn["status"], redrawn["error"], redrawn["hint"]) == (FAILED, summary["error"], summary["hint"])
