"""make run's three runs through one simulator, controller and recorder (``bracing_bringup.session``): each
run's bag equals a fresh bracing-pair run's, message for message (wall times aside), and its summary too (its
wall-time keys aside); a run that needs other processes (another URDF) starts fresh ones."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from ros_helpers import PAPER_YAML, REPO_ROOT, pair_argv
from test_reused_runs import DURATION_S
from test_reused_variants import comparable

from bracing_bringup.run_plan import RunOptions
from bracing_bringup.session import Session, processes_of, reusable
from bracing_core.variants import RUNS

RESET_LINE = "reset_simulation: back to the initial state at t = 0.000000 s"
WALL_KEYS = ("wall_time_s", "real_time_factor")
"""The summary's keys that measure the wall clock."""


def summary_of(out: Path) -> dict[str, Any]:
    """The run's summary.json without its wall-time keys."""
    summary = json.loads((out / "summary.json").read_text())
    return {key: value for key, value in summary.items() if key not in WALL_KEYS}


@pytest.fixture(scope="module")
def fresh_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """RUNS as fresh bracing-pair runs (each its own processes), as make run made them before the session."""
    root = tmp_path_factory.mktemp("fresh")
    for run in RUNS:
        argv = pair_argv(root / run.name, "--duration", str(DURATION_S), "--no-animation", *run.flags().split())
        done = subprocess.run(argv, cwd=REPO_ROOT, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
    return root


def test_make_run_s_three_runs_through_reused_processes_equal_three_fresh_runs(
    tmp_path: Path, fresh_runs: Path
) -> None:
    argv = [sys.executable, "-m", "bracing_bringup.paper_run", "--output", str(tmp_path), "--duration", str(DURATION_S)]
    done = subprocess.run(argv, cwd=REPO_ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    sim_logs = [(tmp_path / run.name / "logs" / "simulator.log").read_text() for run in RUNS]
    assert [log.count(RESET_LINE) for log in sim_logs] == [0, 1, 1]  # one simulator made the three runs, reset
    assert [log.count("subscribers matched") for log in sim_logs] == [1, 0, 0]  # started once
    bags = {run.name: comparable(tmp_path / run.name / "bag") for run in RUNS}
    for run in RUNS:
        assert bags[run.name] == comparable(fresh_runs / run.name / "bag"), run.name  # every topic, every message
        assert summary_of(tmp_path / run.name) == summary_of(fresh_runs / run.name), run.name
    assert bags["passive"]["/controller_state"] != bags["braced"]["/controller_state"]  # three runs, not one thrice


def test_a_run_needing_other_processes_starts_fresh_ones(tmp_path: Path, fresh_runs: Path) -> None:
    """Another URDF (the same robot, another file) is no per-run parameter: the session stops its processes and
    starts new ones, whose run is a fresh run's."""
    urdf = tmp_path / "copy.urdf"
    shutil.copy(REPO_ROOT / "config" / "paper_4link.urdf", urdf)
    braced, passive = RUNS[0], RUNS[1]
    first = RunOptions(PAPER_YAML, tmp_path / "first", DURATION_S, quiet=True, animation=False)
    second = RunOptions(PAPER_YAML, tmp_path / "second", DURATION_S, quiet=True, animation=False, bracing=False)
    second.parameters = {"robot.urdf": str(urdf)}
    assert processes_of(second) != processes_of(first)
    with Session() as session:
        assert session.run(first).exit_code == 0
        assert session.running
        assert session.run(second).exit_code == 0
    assert not session.running
    assert RESET_LINE not in (tmp_path / "first" / "logs" / "simulator.log").read_text()
    assert (tmp_path / "second" / "logs" / "simulator.log").exists()  # a simulator of its own, logged there
    assert str(urdf) in (tmp_path / "second" / "params.yaml").read_text()
    assert comparable(tmp_path / "first" / "bag") == comparable(fresh_runs / braced.name / "bag")
    assert comparable(tmp_path / "second" / "bag") == comparable(fresh_runs / passive.name / "bag")


def test_only_per_run_parameters_and_this_process_s_options_share_the_processes() -> None:
    braced = RunOptions(PAPER_YAML, Path("a"), DURATION_S)
    free = RunOptions(PAPER_YAML, Path("b"), DURATION_S, bracing=False, free_space=True, quiet=True, animation=False)
    assert processes_of(free) == processes_of(braced)
    for other in (
        RunOptions(PAPER_YAML, Path("a"), 2 * DURATION_S),
        RunOptions(PAPER_YAML, Path("a"), DURATION_S, mode="torque"),
        RunOptions(PAPER_YAML, Path("a"), DURATION_S, parameters={"robot.urdf": "other.urdf"}),
    ):
        assert processes_of(other) != processes_of(braced)
    assert reusable(braced)
    assert not reusable(RunOptions(PAPER_YAML, Path("a"), view=True))
    assert not reusable(RunOptions(PAPER_YAML, Path("a"), engine="mujoco"))
    assert not reusable(RunOptions(PAPER_YAML, Path("a"), real_time=True))
