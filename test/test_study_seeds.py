"""Studies you can trust (bracing_experiments.study_runs): every bracing-study form on any scenario
(--config) over several seeds (--seeds), one row per condition and seed in runs.csv, medians with their
spread in the report; the same seed the same run bit for bit, another seed another draw; runs too short
for the hand window refused before any run; and a study on a real Dask cluster (a dask scheduler and two
dask workers, each its own process) giving the local runs' numbers. Short runs (2.05 s: the hand window
[2, 2.05] s fits) and the smallest grids, the machine being shared."""

from __future__ import annotations

import io
import re
import subprocess
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.csv as pa_csv
import pytest
import test_sweep

from bracing_analysis.summary import HAND_ERROR_T_MIN_S, WINDOWED_KEYS
from bracing_core.params import ConfigError
from bracing_experiments.experiment import execute_run
from bracing_experiments.optimize_specs import build_problem
from bracing_experiments.robustness import BRACED, FEEDBACK_LAW, build_robustness
from bracing_experiments.study import main as study_main
from bracing_experiments.study_runs import RUNS_CSV, SEED_KEY, Median, holds_text

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER_YAML = REPO_ROOT / "config" / "paper_4link.yaml"
DURATION = "2.05"  # [s]: the hand window [2, 2.05] s fits
QUICK = ["--duration", DURATION, "--positions", "1", "--trials", "0", "--no-progress"]  # the paper form, smallest
NOT_OUTCOMES = ("wall_time_s", "real_time_factor")  # what depends on the machine, not on the run
dask_cluster = test_sweep.dask_cluster  # a scheduler and two workers (the sweep's distributed test's)


def runs_csv(output: Path) -> list[dict[str, Any]]:
    return pa_csv.read_csv(output / RUNS_CSV).to_pylist()  # type: ignore[no-any-return]


def outcomes(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in row.items() if k not in NOT_OUTCOMES} for row in rows]


def test_another_scenario_over_three_seeds_gives_a_row_per_condition_and_seed_and_the_spread(tmp_path: Path) -> None:
    output = tmp_path / "hyper"
    noise = ["--set", "sensors.position_noise_rad=0.0001"]  # every run draws: each seed its own run
    argv = ["paper", "--config", "hyper_7link", "--seeds", "3", "--output", str(output), "--workers", "2"]
    assert study_main([*argv, *QUICK, *noise]) == 0
    rows = runs_csv(output)
    per_condition = Counter(row["condition"] for row in rows)
    assert len(per_condition) == 8 + 4 + 8 + 3 and set(per_condition.values()) == {3}  # every condition x 3 seeds
    assert {row["seed"] for row in rows} == {0, 1, 2} and all(row["seeded"] for row in rows)  # the file's seed on
    assert {row["run_id"] for row in rows} == {p.name for p in (output / "runs").iterdir()}  # 69 runs, each once
    # Each metric of summary.json is a column; the seeds' draws differ, so do their numbers.
    assert {"hand_rms_error_m", "energy_consumed_j", "normal_force_rms_error_n", "status"} <= set(rows[0])
    braced = [r for r in rows if r["condition"] == "comparison=bracing; bracing=True; input_mode=voltage; "
              "gravity_compensation=False"]  # fmt: skip
    energies = [r["energy_consumed_j"] for r in sorted(braced, key=lambda r: r["seed"])]
    assert len(set(energies)) == 3
    # The report: the window, the seeds, and each figure the median with its range.
    report = (output / "report.md").read_text()
    assert f"count over t in [{HAND_ERROR_T_MIN_S:g}, {DURATION}] s: the last 0.05 s of each {DURATION} s run" in report
    assert "3 seeds (0-2, `sensors.noise_seed`): 23 of 23 conditions draw noise" in report
    hands = [r["hand_rms_error_m"] for r in braced]
    spread = f"{Median(hands):.4g}"
    assert spread == f"{np.median(hands):.4g} ({min(hands):.4g}-{max(hands):.4g})"
    assert f"| yes | voltage | no | {spread} |" in report  # the braced run: hand RMS, its median and range
    # Each conclusion with the number of conditions and seeds it holds in.
    assert re.search(
        r"- Seed by seed, bracing uses less energy than free in \d of 4 conditions, in 3 of 3 seeds", report
    )


def test_a_conclusion_counts_the_conditions_it_holds_in_in_every_seed_and_in_some() -> None:
    held = {"nominal": [True, True, True], "masses x1.3": [True, False, True], "mu 0.3": [False, False, False]}
    assert holds_text(held, 3) == "in 1 of 3 conditions, in 3 of 3 seeds; in 2 of 3 in at least 1 of 3 seeds"
    assert holds_text({"nominal": [True]}, 1) == "in 1 of 1 conditions, in 1 of 1 seed"


def test_the_same_seed_gives_the_same_run_bit_for_bit_and_another_seed_another_draw() -> None:
    study = build_robustness(PAPER_YAML, float(DURATION), levels_per_factor=1, seeds=2)
    sensor = next(f for f in study.factors if f.key == "force_sensor")
    first = study.spec(sensor, sensor.levels[0], FEEDBACK_LAW, BRACED.name)  # force feedback reads the noisy sensor
    seed_1, seed_2 = study.replicas.runs[first.run_id]
    assert (seed_1.sim_params[SEED_KEY], seed_2.sim_params[SEED_KEY]) == (1, 2) and seed_1 is first
    a, again, b = execute_run(seed_1), execute_run(seed_1), execute_run(seed_2)
    for key in ("hand_rms_error_m", "normal_force_rms_error_n", "energy_consumed_j", "copper_loss_j"):
        assert a.row[key] == again.row[key], key
        assert a.row[key] != b.row[key], key
    assert a.arrays is not None and again.arrays is not None
    with np.load(io.BytesIO(a.arrays)) as x, np.load(io.BytesIO(again.arrays)) as y:
        assert all(np.array_equal(x[k], y[k]) for k in x.files)
    # A run that draws nothing random is one run for every seed.
    nominal = next(iter(study.runs.values()))
    assert study.replicas.runs[nominal.run_id] == [nominal, nominal] and not study.replicas.seeded[nominal.run_id]


def test_a_study_of_runs_too_short_for_the_hand_window_runs_and_says_the_hand_is_not_judged(tmp_path: Path) -> None:
    output = tmp_path / "short"
    quick = ["--duration", "1.5", *QUICK[2:]]
    assert study_main(["paper", "--output", str(output), *quick, "--config", str(PAPER_YAML)]) == 0
    report = (output / "report.md").read_text()
    assert "runs of 1.5 s end before that window opens, so they are not measured here (null in runs.csv)" in report
    rows = runs_csv(output)
    assert rows and all(row["hand_rms_error_m"] is None for row in rows)
    with pytest.raises(SystemExit) as exit_:
        study_main(["paper", "--output", str(output), "--seeds", "0"])
    assert exit_.value.code == 2


def test_an_optimisation_judged_on_a_window_that_does_not_fit_is_refused_before_any_trial() -> None:
    force = "contacts.elbow.desired_normal_force"
    with pytest.raises(ConfigError, match=r"--duration 1.5: hand_rms_error_m count over t >= 2 s"):
        build_problem(PAPER_YAML, [f"{force}=0:40"], ["energy_consumed_j"], ["hand_rms_error_m<=0.03"], duration=1.5)
    build_problem(PAPER_YAML, [f"{force}=0:40"], ["energy_consumed_j"], duration=1.5)  # no windowed metric: taken


def test_every_windowed_metric_says_its_window_in_the_output_reference() -> None:
    page = (REPO_ROOT / "docs" / "reference" / "outputs.md").read_text()
    for key in WINDOWED_KEYS:
        line = next(line for line in page.splitlines() if line.startswith(f"| `{key}` |"))
        assert f"t >= {HAND_ERROR_T_MIN_S:g} s" in line, line


def test_a_study_on_a_dask_cluster_gives_the_local_runs(
    tmp_path: Path, dask_cluster: tuple[str, list[subprocess.Popen[bytes]]]
) -> None:
    address, _ = dask_cluster
    argv = ["paper", "--seeds", "2", *QUICK, "--set", "sensors.position_noise_rad=0.0001"]
    assert study_main([*argv, "--output", str(tmp_path / "local"), "--workers", "2"]) == 0
    assert study_main([*argv, "--output", str(tmp_path / "dask"), "--scheduler", address]) == 0
    local, distributed = runs_csv(tmp_path / "local"), runs_csv(tmp_path / "dask")
    assert len(local) == 2 * 23 and outcomes(distributed) == outcomes(local)  # every number, bit for bit
    workers = pa_csv.read_csv(tmp_path / "dask" / "results.csv").column("worker").to_pylist()
    assert len(set(workers)) == 2  # both dask workers ran some
