"""Silent nonsense is said, once, in the node's log and in summary.json's
``warnings``: a braced contact pushed with f_nd <= 0, a braced contact that lets go or is never
reached, a target out of the arm's reach (before the run, from the kinematics), real-time stepping
slower than real time. And bracing-sweep / bracing-study exit 1 when a run failed, 2 on a
configuration error before any run, the study's pre-check running the task-rank check of a run.

The pair runs are real (bracing-pair: three processes over DDS), short (0.3-0.5 s of sim time).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pyarrow.parquet as pq
import pytest
from ros_helpers import PAPER_YAML, pair_argv, run

from bracing_analysis.bag import read_series
from bracing_core import checks
from bracing_core.rollout import build_scenario
from bracing_core.watch import RunWatch
from bracing_engine import ContactEvent, EventKind
from bracing_experiments.experiment import execute_run
from bracing_experiments.running import row_warnings
from bracing_experiments.sweep import build_specs

CONFIG_DIR = PAPER_YAML.parent
SCENARIOS = ("paper_4link", "hyper_7link", "wall_7link", "mobile_8joint", "writing_desk")
# f_nd = -5 N on a unilateral elbow, and the hand's circle moved 0.8 m out: the elbow lets go at
# ~0.12 s, the hand's target leaves the arm's 2 m reach.
NONSENSE = (
    "contacts.elbow.desired_normal_force=-5",
    "contacts.elbow.unilateral=true",
    "hand.trajectory.center=[0.0,1.9,0.6]",
)


# --------------------------------------------------------------------------- the checks themselves


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_reach_bound_is_never_exceeded_by_the_arm(name: str) -> None:
    """The criterion is sound: over random postures within the joint limits, every task frame stays
    within the bound of its first joint; and the shipped scenarios get no warning."""
    scenario = build_scenario(CONFIG_DIR / f"{name}.yaml")
    assert scenario.controller is not None
    plant, config = scenario.controller.plant, scenario.controller.config
    assert checks.configuration_warnings(config, plant) == []
    model = plant.robot.model
    frames = [config.hand.frame, *(c.frame for c in config.shared.braced_contacts)]
    reaches = {frame: checks.frame_reach(model, model.getFrameId(frame)) for frame in frames}
    data = model.createData()
    rng = np.random.default_rng(29)
    low = np.maximum(model.lowerPositionLimit, -np.pi)
    high = np.minimum(model.upperPositionLimit, np.pi)
    for _ in range(300):
        pin.framesForwardKinematics(model, data, rng.uniform(low, high))
        for frame, reach in reaches.items():
            assert reach is not None
            distance = np.linalg.norm(data.oMf[model.getFrameId(frame)].translation - reach.anchor)
            assert distance <= reach.radius + 1e-12, (name, frame)


def test_configuration_warnings_name_the_force_and_the_unreachable_target() -> None:
    scenario = build_scenario(
        PAPER_YAML,
        shared={"contacts.elbow.desired_normal_force": 0.0},
        ctl={"hand.trajectory.center": [0.0, 1.9, 0.6], "contacts.elbow.target": [0.0, 2.5, 0.0]},
    )
    assert scenario.controller is not None
    force, hand, brace = checks.configuration_warnings(scenario.controller.config, scenario.controller.plant)
    assert force.startswith("contacts.elbow.desired_normal_force is 0 N")
    # The paper's arm: 4 x 0.5 m from joint1 at the origin; the circle's far point is (1.9 + 0.2, 0.6).
    assert hand.startswith("hand target out of reach: hand.trajectory (circle) asks for [0, 2.1, 0.6] at t = 0 s")
    assert "2.184 m from joint1 along y, z" in hand and "never more than 2.000 m" in hand
    assert brace.startswith(
        "brace point 'elbow' target out of reach: contacts.elbow.target (hold) asks for [0, 2.5, 0]"
    )
    assert "1.000 m from it" in brace  # the elbow is 2 links from joint1
    assert checks.slow_real_time_warning(0.97, 1.0) is None
    assert "ran at 0.63x real time instead of the requested 1x" in str(checks.slow_real_time_warning(0.63, 1.0))


def test_an_in_process_run_lists_each_warning_once() -> None:
    (spec,) = build_specs(PAPER_YAML, list(NONSENSE), zipped=False, duration=0.5)
    outcome = execute_run(spec)
    assert outcome.summary is not None, outcome.row
    warnings = outcome.summary["warnings"]
    assert [w.split(" ")[0] for w in warnings] == ["hand", "contacts.elbow.desired_normal_force", "contact"]
    assert "let go of its surface at t = 0.1" in warnings[2]
    assert json.loads(outcome.row["warnings"]) == warnings  # and in the sweep's table (JSON, as a list of values)
    assert row_warnings([outcome.row, outcome.row]) == dict.fromkeys(warnings, 2)  # what a sweep prints
    (fine,) = build_specs(PAPER_YAML, [], zipped=False, duration=0.2)
    assert execute_run(fine).summary["warnings"] == []  # type: ignore[index]


# --------------------------------------------------------------------------- over DDS


def _count(text: str, needle: str) -> int:
    return sum(needle in line for line in text.splitlines())


def test_the_nodes_and_the_pairs_summary_say_each_warning_once(tmp_path: Path) -> None:
    out = tmp_path / "nonsense"
    sets = [arg for item in NONSENSE for arg in ("--set", item)]
    done = run(pair_argv(out, "--duration", "0.5", "--no-animation", *sets), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    controller = (out / "logs" / "controller.log").read_text()
    simulator = (out / "logs" / "simulator.log").read_text()
    assert _count(controller, "contacts.elbow.desired_normal_force is -5 N") == 1
    assert _count(controller, "hand target out of reach") == 1
    assert _count(simulator, "contact 'elbow' let go of its surface at t = 0.1") == 1
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    assert len(warnings) == 3, warnings
    assert [w.split(" ")[0] for w in warnings] == ["hand", "contacts.elbow.desired_normal_force", "contact"]
    assert all(f"warning: {w}" in done.stdout for w in warnings)  # bracing-pair prints them


def test_a_braced_contact_that_never_touches_is_warned(tmp_path: Path) -> None:
    """A unilateral braced elbow whose floor is 1 m down starts released and never gets there."""
    out = tmp_path / "unreached"
    sets = ["--set", "contacts.elbow.unilateral=true", "--set", "contacts.elbow.offset=-1.0"]
    done = run(pair_argv(out, "--duration", "0.2", "--no-animation", *sets), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    (warning,) = json.loads((out / "summary.json").read_text())["warnings"]
    assert warning.startswith("contact 'elbow' never touched its surface although the controller braces it")
    assert _count((out / "logs" / "simulator.log").read_text(), warning) == 1


def test_real_time_stepping_slower_than_asked_is_warned_with_the_achieved_factor(tmp_path: Path) -> None:
    out = tmp_path / "fast"
    argv = pair_argv(out, "--duration", "0.3", "--no-animation", "--real-time", "--set", "real_time_factor=50")
    done = run(argv, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    (warning,) = json.loads((out / "summary.json").read_text())["warnings"]
    assert warning.startswith("real-time stepping ran at ") and "instead of the requested 50x" in warning
    achieved = float(warning.split("ran at ")[1].split("x")[0])
    assert 0.0 < achieved < 0.95 * 50
    assert _count((out / "logs" / "simulator.log").read_text(), warning) == 1


# --------------------------------------------------------------------------- exit codes


def _cli(module: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", module, *args, "--no-progress", "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_a_sweep_with_a_failed_run_exits_1_with_its_table(tmp_path: Path) -> None:
    # An elbow 5 cm below its plane is an infeasible start: that run fails, the other does not.
    done = _cli(
        "bracing_experiments.sweep", "--config", str(PAPER_YAML), "--output", str(tmp_path), "--duration", "0.1",
        "--set", "contacts.elbow.offset=0.0,0.05",
    )  # fmt: skip
    assert done.returncode == 1, done.stdout + done.stderr
    assert "(1 ok, 1 failed)" in done.stdout
    rows = pq.read_table(tmp_path / "results.parquet").to_pylist()
    assert sorted(row["status"] for row in rows) == ["failed", "ok"]


def test_the_study_checks_the_task_rank_before_any_run_and_exits_1_when_a_run_fails(tmp_path: Path) -> None:
    # The planar arm cannot move its elbow along x: every braced run would fail on it. Refused first.
    ranked = _cli(
        "bracing_experiments.study", "paper", "--output", str(tmp_path / "rank"), "--duration", "0.1",
        "--positions", "1", "--set", "contacts.elbow.brace_axes=[x]",
    )  # fmt: skip
    assert ranked.returncode == 2, ranked.stdout + ranked.stderr
    assert "contacts.elbow.brace_axes: frame 'elbow' cannot move along x" in ranked.stderr
    assert not (tmp_path / "rank" / "runs").exists()
    # Every run diverges at once (a joint faster than 0.5 rad/s): the report is written, the exit is 1.
    failed = _cli(
        "bracing_experiments.study", "paper", "--output", str(tmp_path / "failed"), "--duration", "0.1",
        "--positions", "1", "--set", "divergence_speed=0.5",
    )  # fmt: skip
    assert failed.returncode == 1, failed.stdout + failed.stderr
    assert "failed: DivergenceError" in (tmp_path / "failed" / "report.md").read_text()


# --------------------------------------------------------------------------- every simulator warning
# The simulator's warnings come from one policy (bracing_core.watch.RunWatch, in the node and in process) and
# reach summary.json by one path: run_status -> the recorder's bag -> the summary (bracing-pair's and
# bracing-report's alike). Each is forced below: in process for the policy, over DDS for the path.


def _in_process(*sets: str, duration: float) -> dict[str, Any]:
    (spec,) = build_specs(PAPER_YAML, list(sets), zipped=False, duration=duration)
    outcome = execute_run(spec)
    assert outcome.summary is not None, outcome.row
    return outcome.summary


def test_a_table_that_pulls_is_warned_and_a_one_sided_one_lets_go_instead() -> None:
    """The paper's voltage law pressing with f_nd = 0.5 N: its force error takes the bilateral floor's
    f_n below zero in 7 % of the 10 s run. One-sided, the elbow lets go there instead. At 1 N it pulls in
    2.7 % of the run: a transient, not a table that pulls (PULL_SHARE)."""
    (pull,) = _in_process("contacts.elbow.desired_normal_force=0.5", duration=10.0)["warnings"]
    assert pull == (
        "contact 'elbow' pulled on its surface (f_n < 0) in 7 % of the run from t = 3.348 s, down to -1.88 N "
        "(mean -0.632 N while pulling): a table cannot pull: set unilateral: true (contacts.elbow.unilateral) and "
        "the contact lets go instead"
    )
    one_sided = _in_process("contacts.elbow.desired_normal_force=0.5", "contacts.elbow.unilateral=true", duration=10.0)
    paper_gains = checks.force_feedback_gains(0.17 / 0.6, 1e-3)  # the paper's motors' L / R at 1 ms
    assert one_sided["warnings"] == [checks.let_go_warning("elbow", 3.348, paper_gains)]
    assert _in_process("contacts.elbow.desired_normal_force=1.0", duration=10.0)["warnings"] == []


FAR_START = [-0.2 * np.pi - 0.1, -0.6 * np.pi + 0.3, 0.8 * np.pi, -0.4 * np.pi]
"""The paper's start with joint1 and joint2 moved off the floor: the projection (nearest in M) moves joint4 most."""


def _start(position: list[float]) -> tuple[str, str]:
    """--set's for a projected start from ``position``."""
    return "project_initial_position=true", "initial_position=" + json.dumps(position).replace(" ", "")


def test_a_far_projection_is_warned_naming_the_joint_and_the_move() -> None:
    (warning,) = _in_process(*_start(FAR_START), duration=0.01)["warnings"]
    assert warning.startswith(
        "project_initial_position moved joint 'joint4' by +0.17 rad (-1.257 -> -1.087 rad) to put the contacts on "
        "their surfaces, more than 0.1 rad (0.01 m): the run starts far from initial_position"
    )
    assert "joint1" not in warning and "joint2" not in warning  # moved 0.018 and 0.065 rad: not far
    near = [-0.2 * np.pi, -0.6 * np.pi + 0.01, 0.8 * np.pi, -0.4 * np.pi]
    assert _in_process(*_start(near), duration=0.01)["warnings"] == []
    # Near a limit, the text says how near.
    text = checks.projection_warning([("wrist", 0.2, 1.52, False, -1.57, 1.57)], "0.1 rad (0.01 m)")
    assert "joint 'wrist' by +1.32 rad (0.200 -> 1.520 rad, 0.05 rad from its upper limit)" in text


def test_a_drifting_contact_and_a_braced_contact_that_never_touches_are_warned_in_process() -> None:
    """A floor 5e-7 m above the elbow's start: within contact_tolerance, held, and off by more than
    DRIFT_WARNING_M from the first state. A one-sided floor 1 m down: never reached."""
    (drift,) = _in_process("contacts.elbow.offset=5e-7", duration=0.05)["warnings"]
    assert drift == (
        "held contact 'elbow' has drifted 5e-07 m off its surface at t = 0.000 s (baumgarte = 0 1/s; raise it, "
        "e.g. 10-200 1/s, to hold the contacts)"
    )
    (never,) = _in_process("contacts.elbow.unilateral=true", "contacts.elbow.offset=-1.0", duration=0.05)["warnings"]
    assert never == checks.never_reached_warning("elbow")


def test_a_bounce_is_neither_an_arrival_nor_a_let_go() -> None:
    """The issue's arm touched down at 4.68 s and let go within the same step: it was said to have let go,
    and never to have been reached. What counts is what the states say: the elbow (4 mm above, so it
    starts released) is fed a bounce within a step, then holds from the state at 0.020 s."""
    sc = build_scenario(PAPER_YAML, shared={"contacts.elbow.unilateral": True, "contacts.elbow.offset": -0.004})
    assert sc.sim_config is not None and not sc.sim.active[0]
    watch = RunWatch(sc.plant, sc.sim_config, sc.sim)
    watch.events(
        [
            ContactEvent(time=0.0105, contact="elbow", kind=EventKind.touchdown),
            ContactEvent(time=0.0107, contact="elbow", kind=EventKind.release),
        ]
    )
    times = np.arange(21) * 1e-3
    held = times > 0.0195
    assert watch.states(times[:11], held[:11, None], np.zeros((11, 1)), np.zeros((11, 1))) == []  # a bounce
    watch.events([ContactEvent(time=0.0193, contact="elbow", kind=EventKind.touchdown)])
    (late,) = watch.states(times[11:], held[11:, None], np.zeros((10, 1)), np.zeros((10, 1)))
    assert late == checks.late_reach_warning("elbow", 0.0193)
    assert watch.finish() == []  # reached: no "never touched"
    watch.events([ContactEvent(time=0.0204, contact="elbow", kind=EventKind.release)])
    (gone,) = watch.states([0.021], [False], [0.0], [0.0])
    assert gone == checks.let_go_warning("elbow", 0.0204, checks.force_feedback_gains(0.17 / 0.6, 1e-3))


def _pair(tmp_path: Path, name: str, *sets: str, extra: tuple[str, ...] = (), duration: str = "0.3") -> Path:
    out = tmp_path / name
    args = [arg for item in sets for arg in ("--set", item)]
    done = run(pair_argv(out, "--duration", duration, "--no-animation", *extra, *args), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    (out / "stdout.txt").write_text(done.stdout)
    return out


def _said(out: Path) -> tuple[list[str], str, str]:
    """summary.json's warnings, bracing-pair's stdout, the simulator's log."""
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    return warnings, (out / "stdout.txt").read_text(), (out / "logs" / "simulator.log").read_text()


def test_the_pair_says_what_the_in_process_run_says_through_the_bag(tmp_path: Path) -> None:
    """A far projection and a table pulling (torque input, f_nd = -5 N): the pair's summary has the same
    warnings as the same run in process, in the same order; each is in bracing-pair's output and once in
    the simulator's log; the bag holds the simulator's, so a report from the bag alone has them too."""
    sets = ("input_mode=torque", "contacts.elbow.desired_normal_force=-5", *_start(FAR_START))
    out = _pair(tmp_path, "pulls", *sets)
    warnings, stdout, log = _said(out)
    assert warnings == _in_process(*sets, duration=0.3)["warnings"]
    assert [w.split(" ")[0] for w in warnings] == [
        "contacts.elbow.desired_normal_force",
        "project_initial_position",
        "contact",
    ]
    assert "pulled on its surface (f_n < 0) in 100 % of the run from t = 0.000 s, down to -5 N" in warnings[2]
    assert all(f"warning: {w}" in stdout for w in warnings)
    assert all(_count(log, w) == 1 for w in warnings[1:])  # the simulator's (the first is the controller's)
    assert read_series(out / "bag").warnings == warnings[1:]


def test_drift_and_saturation_reach_the_summary(tmp_path: Path) -> None:
    """Two the log alone used to say: a held contact drifting past 1e-7 m, and commands saturated at
    motors.voltage_limit (the first of a kind the log repeats, rate-limited)."""
    out = _pair(tmp_path, "drift", "contacts.elbow.offset=5e-7", "motors.voltage_limit=20")
    warnings, stdout, log = _said(out)
    drift = [w for w in warnings if w.startswith("held contact 'elbow' has drifted 5e-07 m")]
    saturated = [w for w in warnings if w.startswith("motor_command saturated to +/-20.0 (first at t = 0.000 s;")]
    assert len(drift) == len(saturated) == 1 and len(warnings) == 2, warnings
    assert all(f"warning: {w}" in stdout and _count(log, w) == 1 for w in warnings)


def test_the_watchdog_reaches_the_summary(tmp_path: Path) -> None:
    """Real-time stepping with a command older than command_timeout (1 us: every one) applies zero."""
    out = _pair(tmp_path, "stale", "command_timeout=1e-6", extra=("--real-time",))
    warnings, stdout, log = _said(out)
    (stale,) = [w for w in warnings if w.startswith("motor_command stale: applying zero (first at t = ")]
    assert f"warning: {stale}" in stdout and _count(log, stale) == 1


def test_a_braced_contact_that_starts_off_its_surface_is_warned_until_it_arrives(tmp_path: Path) -> None:
    """The issue's one-sided table 4 mm under the elbow, without the projection: it touches down 29 ms in,
    and the summary says so (it said nothing: the touchdown counted as reached)."""
    out = _pair(tmp_path, "late", "contacts.elbow.unilateral=true", "contacts.elbow.offset=-0.004")
    warnings, stdout, _ = _said(out)
    assert warnings == [checks.late_reach_warning("elbow", 0.029)]
    assert f"warning: {warnings[0]}" in stdout
