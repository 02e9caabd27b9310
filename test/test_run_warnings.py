"""Issue 29, item 4: silent nonsense is said, once, in the node's log and in summary.json's
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

import numpy as np
import pinocchio as pin
import pyarrow.parquet as pq
import pytest
from ros_helpers import PAPER_YAML, pair_argv, run

from bracing_core import checks
from bracing_core.rollout import build_scenario
from bracing_experiments.experiment import execute_run
from bracing_experiments.sweep import build_specs, row_warnings

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
