"""An exception in a node's per-state path on rcl (C++) never ends it silently: the node says it once at FATAL with
where and rcl's message, flushes what it sent and exits 1; bracing-pair exits 1 with summary.json failed, its
error the node's, and the bag of every state up to the failure.

The fault is real: the node's C++ path meets a real rcl error in the middle of a real run (real processes, real
DDS), given a null rcl handle through bracing_rcl's public API after its first messages by the test-only
``faults/sitecustomize.py`` (no hook in the product). Before: a Python traceback, exit 1, no line of the
node's own, no summary.json.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import pytest
from ros_helpers import isolated_env, pair_argv, run

from bracing_analysis.bag import read_series
from bracing_controller.rcl_path import PATH_WHERE as CONTROLLER_WHERE
from bracing_core.failures import EXIT_NODE_FAILED, FAILED, NODE_FAILED
from bracing_ros.node_failure import PathError, end_run, failure_text
from bracing_sim.node import COMMAND_PATH_WHERE as SIMULATOR_WHERE

FAULTS = Path(__file__).resolve().parent / "faults"
RUN_S = 1.0  # [s] of sim time: 1000 states
TAKEN = 300  # messages the path takes before its handle is null: the failure comes mid-run


def faulty_run(output: Path, module: str, node: str) -> tuple[str, str, dict[str, Any]]:
    """A bracing-pair run of the paper's arm whose ``module`` (the ``node``) fails in its C++ path after TAKEN
    messages, and exits 1: (what bracing-pair said, the node's one FATAL line, summary.json)."""
    path = os.pathsep.join([str(FAULTS), os.environ.get("PYTHONPATH", "")])
    env = isolated_env(PYTHONPATH=path, BRACING_TEST_FAULT=f"{module}:{TAKEN}")
    done = run(pair_argv(output, "--duration", str(RUN_S), "--no-animation"), env=env, timeout=300)
    said = done.stdout + done.stderr
    assert done.returncode == 1, said
    (fatal,) = fatal_lines(output, node)  # said once
    summary = json.loads((output / "summary.json").read_text())
    assert summary["status"] == FAILED and summary["hint"] is None
    return said, fatal, summary


def fatal_lines(output: Path, node: str) -> list[str]:
    return [line for line in (output / "logs" / f"{node}.log").read_text().splitlines() if "[FATAL]" in line]


def test_an_rcl_error_in_the_simulators_command_path_ends_the_run_with_its_summary(tmp_path: Path) -> None:
    output = tmp_path / "run"
    said, fatal, summary = faulty_run(output, "bracing_sim.node", "simulator")
    failure = "RuntimeError: rcl_take_serialized_message failed: subscription pointer is invalid"
    where = re.escape(f"[bracing_simulator]: the run failed in {SIMULATOR_WHERE} at t = ")
    found = re.search(rf"{where}([\d.]+) s: ", fatal)
    assert found is not None and failure in fatal, fatal
    failed_at = float(found[1])
    assert 0.2 < failed_at < RUN_S  # mid-run: TAKEN commands were read first
    assert "error: the simulator failed: the run failed in the motor_command path" in said
    assert summary["error"].startswith(f"the simulator failed: the run failed in {SIMULATOR_WHERE} at t = ")
    assert failure in summary["error"]
    series = read_series(output / "bag")  # flushed: every state up to the one whose command it could not take
    assert abs(series.joint_t[-1] - failed_at) < 1e-9
    assert series.topic_counts["/joint_states"] == round(failed_at / 1e-3) + 1
    assert abs(summary["sim_time_s"] - failed_at) < 1e-9


def test_an_rcl_error_in_the_controllers_path_ends_the_run_with_its_summary(tmp_path: Path) -> None:
    output = tmp_path / "run"
    said, fatal, summary = faulty_run(output, "bracing_controller.node", "controller")
    failure = "RuntimeError: publishing motor_command failed: publisher pointer is invalid"
    assert f"[bracing_controller]: the run failed in {CONTROLLER_WHERE}: {failure}" in fatal, fatal
    assert "error: the controller failed: the run failed in the per-state path" in said
    assert summary["error"].startswith(f"the controller failed: the run failed in {CONTROLLER_WHERE}: {failure}")
    counts = read_series(output / "bag").topic_counts
    answered = counts["/motor_command"]  # flushed: every answer before the failure
    assert TAKEN <= answered < RUN_S / 1e-3
    assert counts["/joint_states"] == answered + 1  # the state it failed to answer, the last the simulator sent
    assert not fatal_lines(output, "simulator")  # stopped by bracing-pair, not failed


class Said:
    """A node logger's lines, by level."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def fatal(self, message: str) -> None:
        self.lines.append(("fatal", message))

    def error(self, message: str) -> None:
        self.lines.append(("error", message))


def test_any_other_exception_is_said_with_the_function_it_came_through_and_a_failed_flush_too(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Outside a PathError, where is the innermost function (a C++ call's caller); a flush that fails after the
    failure (rcl may be what failed) is said as well, and the exit code stays 1."""

    def publish_state() -> None:
        raise ValueError("a state's vectors do not fit its layout")

    def flush() -> None:
        raise RuntimeError("publisher's context is invalid")

    said = Said()
    try:
        publish_state()
    except ValueError as exc:
        assert end_run(said, exc, flush, " at t = 0.5 s") == EXIT_NODE_FAILED == 1
    where = r"test_node_failures\.test_any_other_exception_[a-z_]+\.<locals>\.publish_state \(line \d+\)"
    what = " at t = 0.5 s: ValueError: a state's vectors do not fit its layout"
    (fatal, error) = said.lines
    assert fatal[0] == "fatal" and re.fullmatch(f"the run failed in {where}{re.escape(what)}", fatal[1]), fatal
    assert error == ("error", "flushing after the failure failed too: RuntimeError: publisher's context is invalid")
    assert capsys.readouterr().err == f"{NODE_FAILED}{fatal[1].removeprefix('the run failed in ')}\n"
    wrapped = PathError("the motor_command path", RuntimeError("rcl_take failed"))
    assert failure_text(wrapped) == "the motor_command path: RuntimeError: rcl_take failed"
