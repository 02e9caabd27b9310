"""The in-process run and bracing-pair's run of the same file agree bit for bit, on every shipped scenario.

Sweeps, studies and the optimiser run a file in one process (``bracing_experiments.experiment.execute_run``
on the engine's rollout); bracing-pair runs it as two node processes over DDS and reads its numbers back
from the recorded bag. Both step the same engine in the same lockstep order, so the two must agree to the
last bit: a redundant arm's null space grows any ulp (paths one rounding apart drift 1e-6 at 3 s), so a
tolerance would only hide a second implementation somewhere. Each recorded series (as
``bracing_analysis`` reads it) and each summary.json metric is compared with ``==``.

The law's time was such a second implementation: the rollout passed t = k * h, the node its stamp
k * step_ns * 1e-9; the two differ by an ulp from k = 11 on. The circle's reference then parted by an ulp
(hyper_7link's commands from row 177, ur5_table's from row 22 through its force-feedback integral, the
paper arm's from row 289), and a TIAGo's 10 s energy by 1e-4. Every case here failed so before it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import CONFIG_DIR
from ros_helpers import pair_argv, run

import bracing_engine as engine
from bracing_analysis.bag import read_series
from bracing_analysis.series import BagSeries
from bracing_analysis.summary import flat_summary
from bracing_core.overrides import route
from bracing_core.rollout import RunResult, Scenario, build_scenario, run_recorded
from bracing_experiments.executors import LocalExecutor
from bracing_experiments.experiment import execute_run, series_from_recording
from bracing_experiments.optimize_report import BEST_YAML
from bracing_experiments.optimize_search import optimize
from bracing_experiments.optimize_specs import build_problem
from bracing_experiments.specs import make_spec

REAL_SENSING = {
    "sensors.noise_seed": 3,
    "sensors.position_noise_rad": 1e-4,
    "sensors.encoder_counts_per_rev": 4096,
    "sensors.force_noise_n": 0.2,
    "sensors.force_bias_n": 0.3,
    "sensors.current_noise_a": 0.01,
    "sensors.command_latency_steps": 1,
    "contacts.elbow.force_feedback.kp": 0.3,
    "contacts.elbow.force_feedback.ki": 100.0,
    "plant_error.mass_scale": 1.2,
}
CASES = [pytest.param(path, {}, id=path.stem) for path in sorted(CONFIG_DIR.glob("*.yaml"))] + [
    pytest.param(CONFIG_DIR / "ur5_table.yaml", {"input_mode": "voltage"}, id="ur5_table-voltage"),
    pytest.param(CONFIG_DIR / "paper_4link.yaml", REAL_SENSING, id="paper_4link-sensed"),
]
"""Every shipped scenario as its file has it, the real arm in voltage input (its file's other mode), and the
paper arm sensed as a real arm is (seeded noise, encoder, latency, force feedback, a heavier plant)."""
SECONDS = 0.4
"""[s] Long enough that every shipped scenario's commands parted before the fix (the last, the paper arm's,
at row 289), short enough for six pair runs."""
WALL_CLOCK_KEYS = {"wall_time_s", "real_time_factor"}
"""Summary keys measured on the wall clock: the only ones the two runs cannot share."""
SERIES = ("joint_t", "t", "hand_desired", "hand_actual", "motor_t", "energy_consumed",
          "energy_net", "copper_loss", "command", "hand_orientation_error")  # fmt: skip
CONTACT_SERIES = ("t", "normal_force", "friction_force", "residual", "active", "position", "slip_velocity",
                  "normal_force_desired", "brace_desired", "brace_actual", "normal_force_error")  # fmt: skip


def differing(pair: np.ndarray, in_process: np.ndarray) -> str | None:
    """None if the two arrays are the same bits (NaN where NaN); else where they first part, and by how much."""
    a, b = np.asarray(pair, dtype=float), np.asarray(in_process, dtype=float)
    if a.size == 0 and b.size == 0:  # a series neither has (an orientation error without the task)
        return None
    if a.shape != b.shape:
        return f"shapes {a.shape} (pair) and {b.shape} (in process)"
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    if same.all():
        return None
    rows = np.flatnonzero(~same.reshape(len(a), -1).all(axis=1)) if a.ndim else np.array([0])
    return f"first at row {int(rows[0])} of {len(a)}, at most {float(np.nanmax(np.abs(a - b))):.3e}"


def series_differences(bag: BagSeries, recording: RunResult) -> dict[str, str]:
    """Each series of the pair's bag that is not the same bits as the in-process recording's."""
    rec = series_from_recording(recording)
    found = {name: differing(getattr(bag, name), getattr(rec, name)) for name in SERIES}
    published = recording.measured_position if recording.measured_position.size else recording.position
    found["joint_position"] = differing(bag.joint_position, published)  # what joint_states carries: as sensed
    assert set(bag.contacts) == set(rec.contacts)
    for contact, series in rec.contacts.items():
        for name in CONTACT_SERIES:
            found[f"{contact}.{name}"] = differing(getattr(bag.contacts[contact], name), getattr(series, name))
    return {name: why for name, why in found.items() if why is not None}


def metric_differences(pair: dict[str, Any], in_process: dict[str, Any]) -> dict[str, tuple[Any, Any]]:
    """Each summary.json entry (flattened) the two runs do not share bit for bit, wall-clock ones aside
    (the in-process summary may hold more: a sweep's extra columns)."""
    a, b = flat_summary(pair), flat_summary(in_process)
    found = {}
    for key in sorted(a):
        if key in WALL_CLOCK_KEYS or key.endswith(tuple(f".{k}" for k in WALL_CLOCK_KEYS)):
            continue
        x, y = a.get(key, "absent"), b.get(key, "absent")
        both_nan = isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)
        if x != y and not both_nan:
            found[key] = (x, y)
    return found


def pair_run(
    config: Path, output: Path, seconds: float | None = None, sets: dict[str, Any] | None = None
) -> tuple[BagSeries, dict[str, Any]]:
    """bracing-pair's run of ``config`` (for ``seconds``, or the file's duration; ``sets``: its --set
    overrides): its bag as bracing_analysis reads it, and its summary.json."""
    duration = [] if seconds is None else ["--duration", str(seconds)]
    overrides = [arg for key, value in (sets or {}).items() for arg in ("--set", f"{key}={value}")]
    done = run(pair_argv(output, *duration, *overrides, "--no-animation", config=config), timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return read_series(output / "bag"), json.loads((output / "summary.json").read_text())


def in_process_scenario(config: Path, sets: dict[str, Any]) -> Scenario:
    """The scenario of ``config`` with ``sets`` routed to their nodes as bracing-pair's --set routes them."""
    routed = route(sets)
    return build_scenario(config, shared=routed.shared, sim=routed.simulator, ctl=routed.controller)


@pytest.mark.parametrize(("config", "sets"), CASES)
def test_the_pairs_bag_and_summary_are_the_in_process_run_bit_for_bit(
    config: Path, sets: dict[str, Any], tmp_path: Path
) -> None:
    bag, summary = pair_run(config, tmp_path / config.stem, SECONDS, sets)
    recording = run_recorded(in_process_scenario(config, sets), SECONDS)
    assert series_differences(bag, recording) == {}
    outcome = execute_run(make_spec(config, {}, SECONDS, overrides=sets))  # a sweep's, a study's, the optimiser's
    assert outcome.summary is not None, outcome.row
    in_process = outcome.summary
    assert summary["status"] == "ok" and summary["energy_consumed_j"] > 0.0
    assert metric_differences(summary, in_process) == {}


def test_the_optimisers_best_on_a_redundant_arm_is_what_bracing_pair_runs(tmp_path: Path) -> None:
    """bracing-optimize on the 7-link arm (two elbows braced, a null space of its own), then its best.yaml
    run by bracing-pair: every summary metric equals the best trial's row, the hand errors too (the run
    passes 2 s, where they start), as the issue's TIAGo did not (70.0767 J against 70.0693 J)."""
    config = CONFIG_DIR / "hyper_7link.yaml"
    vary = ["contacts.elbow1.desired_normal_force=5:15", "contacts.elbow2.desired_normal_force=5:15"]
    problem = build_problem(config, vary, ["energy_consumed_j"], duration=2.2)
    with LocalExecutor(1) as executor:
        found = optimize(problem, tmp_path / "opt", executor, trials=2, progress=False, references=False)
    assert found.best is not None
    row = found.best.user_attrs["row"]
    _, summary = pair_run(tmp_path / "opt" / BEST_YAML, tmp_path / "pair")  # as is: its duration is the trial's
    assert summary["hand_rms_error_m"] is not None and summary["hand_rms_error_m"] == row["hand_rms_error_m"]
    numbers = {key: value for key, value in flat_summary(summary).items() if not isinstance(value, str | list | dict)}
    assert metric_differences(numbers, row) == {}


def test_every_reader_of_a_stamp_gets_the_same_seconds() -> None:
    """The law's time in the node (its state's stamp), the rollout's time column and the bag's time base
    (bracing_analysis) are one conversion of the integer stamp; k * step, the rollout's former time, is not."""
    scenario = build_scenario(CONFIG_DIR / "paper_4link.yaml")
    step_ns = scenario.sim.step_ns
    assert step_ns == 1_000_000
    recording = run_recorded(scenario, 0.2)
    stamps = np.arange(recording.time.size, dtype=np.int64) * step_ns
    assert [engine.stamp_seconds(int(ns)) for ns in stamps] == recording.time.tolist()
    many = np.arange(100_000, dtype=np.int64) * step_ns  # 100 s of 1 ms states
    assert [engine.stamp_seconds(int(ns)) for ns in many] == (many * 1e-9).tolist()  # bag.py's time base
    assert (np.arange(100_000) * 1e-3 != many * 1e-9).sum() == 26_551  # the former k * h: 27 % off by an ulp
