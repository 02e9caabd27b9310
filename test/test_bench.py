"""make bench, quick: every documented key of bench/latest.json is produced and finite.

``python bench/run.py --quick`` runs every figure for about a second or less (its numbers are not
measurements), so a bench broken by a change elsewhere fails ``make test`` and not only the next
``make bench``. MuJoCo (requirements.lock, installed by the set-up for bracing-pair --engine mujoco)
may still be missing from an older environment: without it the MuJoCo keys are null and the output
says why.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from bracing_bringup.paper_run import RUNS

REPO_ROOT = Path(__file__).resolve().parents[1]
BENCH = REPO_ROOT / "bench" / "run.py"

# The keys SPEC.md documents (sections 5, 6 and 8).
SPEC_KEYS = (
    "engine_steps_per_s",
    "mujoco_steps_per_s",
    "engine_vs_mujoco",
    "pair_real_time_factor",
    "dds_bound_real_time_factor",
    "pair_vs_bound",
    "controller_update_us_p50",
    "controller_update_us_p99",
    "scaling",
    "startup_s",
    "stepping_s",
    "shutdown_s",
    "report_s",
    "whole_run_s",
    "sweep_runs_per_min",
    "sweep_parallel_efficiency",
    "rollout_steps_per_s",
    "rollout_hyper_7link_steps_per_s",
    "engine_hyper_7link_step_us",
    "simulator_step_us",
    "pair_real_time_factor_no_recorder",
    "optimize_trials_per_min",
    "pair_step_breakdown_us",
    "collision_share_of_step",
    "dds_bound_rcl_real_time_factor",
    "pair_vs_rcl_bound",
)
# What the bench's table and the docs' Performance page (docs/results/performance.md) report besides.
REPORTED_KEYS = (
    "pair_real_time_factor_whole_run",
    "recorder_share_of_step",
    "recorder_cpu_us_per_state",
    "recorder_cpu_share_of_step",
    "last_step_to_last_file_s",
    "tiny_run_command_s",
    "make_run_s",
    "make_run_stepping_s",
    "make_run_vs_stepping",
    "dds_bound_objects_real_time_factor",
    "bare_import_s",
    "targets",
    "controller_callback_us_p50",
    "controller_callback_us_p99",
    "controller_callback_us_p99_9",
    "controller_callback_us_max",
)
MUJOCO_KEYS = ("mujoco_steps_per_s", "mujoco_samples", "engine_vs_mujoco")


def _numbers(value: Any, where: str) -> list[tuple[str, float]]:
    """Every number in ``value`` (nested dicts and lists), with its place."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return []
    if isinstance(value, (int, float)):
        return [(where, float(value))]
    if isinstance(value, dict):
        return [item for key, inner in value.items() for item in _numbers(inner, f"{where}.{key}")]
    if isinstance(value, list):
        return [item for k, inner in enumerate(value) for item in _numbers(inner, f"{where}[{k}]")]
    raise AssertionError(f"{where}: unexpected {type(value).__name__}")


def test_quick_bench_produces_every_key(tmp_path: Path) -> None:
    output = tmp_path / "latest.json"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONUNBUFFERED="1")
    start = time.monotonic()
    bench = subprocess.Popen(
        [sys.executable, str(BENCH), "--quick", "--output", str(output), "--record", str(tmp_path / "bench.json")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=REPO_ROOT,
        env=env,
        start_new_session=True,  # its process group: the pairs and workers it starts go with it on a timeout
    )
    try:
        stdout, stderr = bench.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        os.killpg(bench.pid, signal.SIGKILL)
        stdout, stderr = bench.communicate()
        raise AssertionError(
            f"bench/run.py --quick did not finish in 300 s:\n{stdout[-3000:]}\n{stderr[-3000:]}"
        ) from None
    took = time.monotonic() - start  # about 25 s on the 2-core VM; the timeout bounds it
    assert bench.returncode == 0, f"bench/run.py --quick failed after {took:.0f} s:\n{stdout[-3000:]}\n{stderr[-3000:]}"
    result = json.loads(output.read_text())
    assert result["quick"] is True
    _check_recorded(result, json.loads((tmp_path / "bench.json").read_text()))

    missing = [key for key in (*SPEC_KEYS, *REPORTED_KEYS) if key not in result]
    assert not missing, f"keys not produced: {missing}"

    has_mujoco = importlib.util.find_spec("mujoco") is not None
    if has_mujoco:
        assert result["mujoco_missing"] is None
    else:
        for key in MUJOCO_KEYS:
            assert result[key] is None, key
        assert "mujoco not installed" in result["mujoco_missing"]
        assert "mujoco not installed" in stdout
    for key in (*SPEC_KEYS, *REPORTED_KEYS):
        if key in MUJOCO_KEYS and not has_mujoco:
            continue
        assert result[key] is not None, f"{key} is null"
        assert _numbers(result[key], key), f"{key}: no number in {result[key]!r}"

    # Every number anywhere in the output is finite (samples, timelines, nested figures too).
    bad = [(where, value) for where, value in _numbers(result, "latest") if not math.isfinite(value)]
    assert not bad, f"non-finite values: {bad}"

    # The nested figures have every entry.
    for p in ("p1", "p2"):
        assert set(result["scaling"][p]["steps_per_s"]) == {"4", "8", "16", "32"}
        assert "cost_exponent" in result["scaling"][p]
    assert set(result["sweep_runs_per_min"]) == {"local_1", "local_2", "dask_local_2"}
    assert result["make_run_runs"] == [run.name for run in RUNS]  # every run of make run timed
    # Where a step goes: every part, each node's work read from its own log, and the parts add up.
    parts = result["pair_step_breakdown_us"]
    named = ("simulator_node", "engine", "controller_node", "law", "dds_round_trip", "recorder")
    beside = ("dds_bound_round_trip", "simulator_reports_overlapped", "controller_state_overlapped")
    beside += ("simulator_dds_writes", "controller_dds_writes")
    assert set(parts) == {"step", *beside, *named}
    assert math.isclose(sum(parts[name] for name in named), parts["step"], rel_tol=1e-9)
    # The recorder's process CPU while the pair stepped, from its own log, over the recorded step.
    assert result["recorder_cpu_us_per_state"] > 0
    step_us = 1e3 / result["pair_real_time_factor"]
    assert math.isclose(
        result["recorder_cpu_share_of_step"], result["recorder_cpu_us_per_state"] / step_us, rel_tol=1e-9
    )
    callback = [result[f"controller_callback_us_{key}"] for key in ("p50", "p99", "p99_9", "max")]
    assert 0 < callback[0] <= callback[1] <= callback[2] <= callback[3]  # the tail, in order
    assert result["pair_vs_rcl_bound"] == result["pair_real_time_factor"] / result["dds_bound_rcl_real_time_factor"]
    for work in result["node_work_us"]:
        for node in ("simulator", "controller"):
            assert work[node]["steps"] >= 1 and 0 < work[node]["p50"] <= work[node]["p99"]
            assert 0 < work[node]["writes_mean"] <= work[node]["mean"]  # rclpy's publish, inside the step's work
        for node in ("simulator", "controller"):  # the answer (state, command) is out before the reports
            assert 0 < work[node]["out_mean"] <= work[node]["mean"]


def _check_recorded(result: dict[str, Any], recorded: dict[str, Any]) -> None:
    """The recorded file (docs/results/data/bench.json's format) is bench/latest.json's figures with when, from
    which commit and on which machine they were measured, and the Performance page's tables render from it."""
    sys.path.insert(0, str(REPO_ROOT / "tools"))
    import bench_tables

    head = subprocess.run(
        ["git", "-C", str(REPO_ROOT), "rev-parse", "--short=7", "HEAD"], capture_output=True, text=True
    )
    assert {k: v for k, v in recorded.items() if k != "recorded"} == {
        k: v for k, v in result.items() if k != "recorded"
    }
    assert recorded["recorded"]["commit"] == head.stdout.strip() and recorded["recorded"]["date"] == time.strftime(
        "%Y-%m-%d", time.gmtime()
    )
    assert recorded["recorded"]["machine"]["cores"] == os.cpu_count()
    for name, table in bench_tables.TABLES.items():
        assert table(recorded).startswith("| "), name
