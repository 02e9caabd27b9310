"""bracing-optimize: a known optimum found through the sweeps' executor, best.yaml reproduced by
bracing-pair, a resumed study after Ctrl-C, and a bad --vary refused before any trial."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from ctrl_c import main_interrupted_after
from ros_helpers import PAPER_YAML, isolated_env, pair_argv, run

from bracing_experiments import optimize as optimize_cli
from bracing_experiments import optimize_search
from bracing_experiments.executors import LocalExecutor
from bracing_experiments.optimize_report import BEST_YAML, TRIALS_PARQUET
from bracing_experiments.optimize_search import open_study, optimize
from bracing_experiments.optimize_specs import build_problem
from bracing_experiments.recorded import TABLES_FILE, render_table

FORCE = "contacts.elbow.desired_normal_force"
TARGET_Y = "contacts.elbow.target[1]"


def _cli(output: Path, *extra: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "bracing_experiments.optimize",
        "--config",
        str(PAPER_YAML),
        "--output",
        str(output),
        "--no-progress",
        *extra,
    ]


def test_torque_mode_force_error_is_minimised_at_the_known_optimum(tmp_path: Path) -> None:
    # A known optimum through the real runs: with torque input f_n = f_nd at every step (eq. 40), so
    # the mean normal force is f_nd; minimised subject to >= 12 N, the optimum is the bound, 12 N.
    problem = build_problem(
        PAPER_YAML,
        [f"{FORCE}=5:30"],
        ["contacts.elbow.normal_force_mean_n"],
        ["contacts.elbow.normal_force_mean_n>=12"],
        duration=0.2,
        sets=["input_mode=torque"],
    )
    with LocalExecutor(2) as executor:
        found = optimize(problem, tmp_path, executor, trials=30, progress=False, references=False)
    assert found.best is not None and found.trials == 30
    assert found.best.params[FORCE] == pytest.approx(12.0, abs=0.6)
    assert found.best.values[0] == pytest.approx(found.best.params[FORCE], abs=1e-6)  # f_n = f_nd
    table = pq.read_table(tmp_path / TRIALS_PARQUET).to_pylist()
    assert len(table) == 30 and {row["status"] for row in table} <= {"ok", "infeasible"}
    assert all((row["status"] == "ok") == (row[FORCE] >= 12 - 1e-6) for row in table)


def test_best_yaml_reproduces_its_trial_through_bracing_pair(tmp_path: Path) -> None:
    out = tmp_path / "opt"
    done = subprocess.run(
        _cli(
            out,
            "--vary",
            f"{FORCE}=0:40",
            "--vary",
            f"{TARGET_Y}=0.35:0.85",
            "--minimize",
            "energy_consumed_j",
            "--trials",
            "4",
            "--workers",
            "2",
            "--duration",
            "2.5",  # hand errors are measured over t >= 2 s
        ),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    best = out / BEST_YAML
    assert best.is_file() and (out / "report.md").is_file() and (out / "trials.csv").is_file()
    study = open_study(
        build_problem(PAPER_YAML, [f"{FORCE}=0:40", f"{TARGET_Y}=0.35:0.85"], ["energy_consumed_j"]), out
    )
    trial = min((t for t in study.trials if t.user_attrs.get("status") == "ok"), key=lambda t: t.values[0])
    expected = trial.user_attrs["row"]
    pair = tmp_path / "pair"
    result = run(pair_argv(pair, config=best), env=isolated_env(), timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    summary = json.loads((pair / "summary.json").read_text())
    assert summary["sim_time_s"] == pytest.approx(2.5)
    for key in ("energy_consumed_j", "hand_rms_error_m", "hand_max_error_m", "copper_loss_j", "brace_rms_error_m"):
        assert summary[key] == expected[key], key  # bit for bit: the law's time is the stamp on both paths


def test_ctrl_c_keeps_finished_trials_and_the_same_command_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The command, Ctrl-C'd once its third trial is told (a SIGINT to its process then, whatever the
    machine's pace): exit 130, exactly those three trials kept, and the same command with 4 more trials
    runs 4, keeping the three as they were."""
    args = ["--vary", f"{FORCE}=0:40", "--minimize", "energy_consumed_j", "--workers", "1", "--duration", "0.5"]
    argv = _cli(tmp_path, *args, "--trials", "40")[3:]
    code, told = main_interrupted_after(optimize_cli.main, argv, monkeypatch, optimize_search, "_record", 3)
    err = capsys.readouterr().err
    assert code == 130 and "interrupted" in err, err
    problem = build_problem(PAPER_YAML, [f"{FORCE}=0:40"], ["energy_consumed_j"], duration=0.5)
    before = {t.number: (t.params, t.values) for t in open_study(problem, tmp_path).trials if "status" in t.user_attrs}
    assert sorted(before) == [trial.number for _, trial, _, _ in told] and len(before) == 3
    table = pq.read_table(tmp_path / TRIALS_PARQUET).to_pylist()
    assert {row["trial"] for row in table if row["status"] != "interrupted"} == set(before)

    total = len(before) + 4
    done = subprocess.run(_cli(tmp_path, *args, "--trials", str(total)), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"{total} trials (4 now" in done.stdout
    after = {t.number: (t.params, t.values) for t in open_study(problem, tmp_path).trials if "status" in t.user_attrs}
    assert len(after) == total
    assert all(after[n] == before[n] for n in before)  # kept, not redone


def test_a_ctrl_c_while_a_trial_is_told_keeps_that_trial_whole(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The Ctrl-C that CI's timing found: it arrives while the second trial is being told, so
    # _record defers it to the moment after that trial is complete. The way out must not tell the
    # finished trial again (Optuna: "Cannot tell a COMPLETE trial"), and both trials stay whole.
    told: list[int] = []

    def tell_then_ctrl_c(study, trial, problem, row):  # type: ignore[no-untyped-def]
        told.append(trial.number)
        if len(told) == 2:
            os.kill(os.getpid(), signal.SIGINT)  # lands inside _record's deferral
        return real_tell(study, trial, problem, row)

    real_tell = optimize_search._tell
    monkeypatch.setattr(optimize_search, "_tell", tell_then_ctrl_c)
    problem = build_problem(PAPER_YAML, [f"{FORCE}=0:40"], ["energy_consumed_j"], duration=0.1)
    with LocalExecutor(1) as executor, pytest.raises(KeyboardInterrupt):
        optimize(problem, tmp_path, executor, trials=10, progress=False, references=False)
    trials = open_study(problem, tmp_path).trials
    assert [t.number for t in trials if "status" in t.user_attrs] == told == [0, 1]
    assert all(t.state.name == "COMPLETE" and t.values for t in trials[:2])
    assert all(t.state.name == "FAIL" for t in trials[2:])  # asked with them, interrupted
    table = pq.read_table(tmp_path / TRIALS_PARQUET).to_pylist()
    assert [row["status"] for row in table][:2] == ["ok", "ok"]


@pytest.mark.parametrize(
    ("vary", "named"),
    [
        ("contacts.elbow.desired_normal_forse=0:40", "contacts.elbow.desired_normal_forse"),
        (f"{FORCE}=40:0", FORCE),
        ("contacts.elbow.friction=-1:0.5", "contacts.elbow.friction"),
        ("contacts.elbow.target[5]=0:1", "contacts.elbow.target[5]"),
        ("input_mode=0:1", "input_mode"),
        ("hand.kp=1:2", "hand.kp"),
    ],
)
def test_a_bad_vary_fails_before_any_trial_naming_it(tmp_path: Path, vary: str, named: str) -> None:
    done = subprocess.run(
        _cli(tmp_path, "--vary", vary, "--minimize", "energy_consumed_j"), capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2, done.stderr
    assert named in done.stderr
    assert not (tmp_path / "study.db").exists()


def test_an_unknown_metric_fails_before_any_trial(tmp_path: Path) -> None:
    done = subprocess.run(
        _cli(tmp_path, "--vary", f"{FORCE}=0:40", "--minimize", "energy_j"), capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2 and "energy_j" in done.stderr, done.stderr
    assert not (tmp_path / "study.db").exists()


def test_the_optimiser_records_its_search_and_optimum_in_tables_json(tmp_path: Path) -> None:
    """DIR/tables.json: the search's facts, the report's optimum and runs tables byte for byte, the provenance."""
    problem = build_problem(PAPER_YAML, [f"{FORCE}=5:30"], ["energy_consumed_j"], duration=0.05)
    with LocalExecutor(1) as executor:
        found = optimize(problem, tmp_path, executor, trials=3, progress=False, seed=7, references=False)
    assert found.best is not None
    recorded = json.loads((tmp_path / TABLES_FILE).read_text())
    assert recorded["study"] == "optimize" and recorded["config"] == PAPER_YAML.name
    assert set(recorded["recorded"]) == {"date", "time_utc", "commit", "dirty", "machine"}
    search = recorded["tables"]["search"]
    header = ["trials", "feasible", "infeasible", "failed", "sampler", "best trial", "this invocation"]
    assert search["header"] == header
    facts = dict(zip(search["header"], search["rows"][0], strict=True))
    assert (facts["trials"], facts["feasible"], facts["failed"]) == ("3", "3", "0")
    assert facts["sampler"] == "TPE (Optuna), seed 7" and facts["best trial"] == str(found.best.number)
    assert facts["this invocation"].startswith("3 trials in ")
    optimum = recorded["tables"]["optimum"]
    assert optimum["rows"] == [[FORCE, "10", f"{found.best.params[FORCE]:.4g}"]]
    report = (tmp_path / "report.md").read_text()
    for key in ("optimum", "optimum-2"):
        assert render_table(recorded["tables"][key]) in report
    assert recorded["tables"]["optimum-2"]["rows"][0][1] == f"{found.best.values[0]:.4g}"
