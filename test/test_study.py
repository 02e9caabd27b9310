"""bracing-study: the paper's three comparisons in one report (short runs: the claims that hold from
the first seconds on; the full 10 s study is in docs/results/index.md): braced / passive / free, the gains, the
placement grid and the optimiser's answer beside it."""

from __future__ import annotations

import re
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from bracing_bringup.paper_run import RUNS
from bracing_bringup.run_plan import RunOptions, command_line
from bracing_core.params import ConfigError
from bracing_core.rollout import build_scenario, run_recorded
from bracing_experiments.executors import LocalExecutor
from bracing_experiments.experiment import FORCE_MAX_ERROR_KEY, STATUS_OK, summarize
from bracing_experiments.optimize_search import open_study
from bracing_experiments.running import RESULTS_PARQUET, ResultsStore, run_sweep
from bracing_experiments.study import (
    PAPER_HAND_RMS_BOUND,
    build_study,
    placement_search,
    resolve_scenario,
    run_placement_search,
    write_report,
)

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER_YAML = REPO_ROOT / "config" / "paper_4link.yaml"


def test_paper_names_the_paper_scenario(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO_ROOT)
    assert resolve_scenario("paper").resolve() == PAPER_YAML.resolve()
    assert resolve_scenario(str(PAPER_YAML)) == PAPER_YAML
    with pytest.raises(ConfigError, match="no_such_scenario"):
        resolve_scenario("no_such_scenario")


def test_the_study_reproduces_the_papers_comparisons(tmp_path: Path) -> None:
    study = build_study(PAPER_YAML, duration=2.5, positions=2, span=0.1, force_scales=(1.0, 2.0))
    assert (len(study.bracing), len(study.passive), len(study.gains), len(study.placement)) == (8, 4, 8, 4)
    assert study.contact == "elbow" and study.axis == "y"
    assert study.targets == pytest.approx([0.5878 - 0.1, 0.5878 + 0.1], abs=1e-4)  # the elbow starts at y = 0.5878
    assert study.forces == [10.0, 20.0]
    with LocalExecutor(2) as executor:
        result = run_sweep(study.specs, tmp_path, executor, progress=False)
        assert result.ran == 24 and result.failed == 0
        store = ResultsStore(tmp_path)
        stored = {spec.run_id: row for spec in study.specs if (row := store.row(spec.run_id)) is not None}
        search = run_placement_search(placement_search(study, stored, tmp_path), executor, trials=6, progress=False)
    report = write_report(study, tmp_path, result.wall_time_s, "test", search=search).read_text()
    for figure in ("bracing.png", "gains.png", "placement.png"):
        assert f"]({figure})" in report
        assert (tmp_path / figure).stat().st_size > 10_000
    rows = {row["run_id"]: row for row in pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist()}
    assert all(row["status"] == STATUS_OK for row in rows.values())

    # 1. bracing lowers the energy (paper, no gravity compensation), for both inputs.
    by_case = {
        (s.varied["bracing"], s.varied["input_mode"], s.varied["gravity_compensation"]): rows[s.run_id]
        for s in study.bracing
    }
    for mode in ("voltage", "torque"):
        braced, free = by_case[(True, mode, False)], by_case[(False, mode, False)]
        assert braced["energy_consumed_j"] < 0.5 * free["energy_consumed_j"]
        assert braced["hand_rms_error_m"] < free["hand_rms_error_m"]
        assert free["normal_force_rms_error_n"] is None and free["bracing"] is False  # no brace: n/a
    assert by_case[(True, "torque", False)]["copper_loss_j"] is None  # direct drive: no circuit

    # 2. torque input: f_n = f_nd to machine precision at every gain; the positions degrade as gains drop.
    gains = {(s.varied["input_mode"], s.varied["gain_scale"]): rows[s.run_id] for s in study.gains}
    for scale in (1.0, 0.5, 0.2, 0.1):
        assert gains[("torque", scale)][FORCE_MAX_ERROR_KEY] < 1e-9
        assert gains[("voltage", scale)][FORCE_MAX_ERROR_KEY] > 1.0  # the voltage transient
    for mode in ("torque", "voltage"):
        assert gains[(mode, 0.1)]["hand_rms_error_m"] > 3 * gains[(mode, 1.0)]["hand_rms_error_m"]
    assert re.search(r"Torque input: the largest force error over every gain scale is \d\.\de-1[45] N", report)

    # 3. the best cell is the grid's least energy, named in the report.
    energies = {
        (s.varied["brace_target"], s.varied["desired_normal_force"]): rows[s.run_id]["energy_consumed_j"]
        for s in study.placement
    }
    (target, force), least = min(energies.items(), key=lambda item: item[1])
    assert f"least energy consumed: {least:.4g} at target y = {target:.3f} m, f_nd = {force:g} N" in report

    # The report's tables hold the rows' numbers.
    braced = by_case[(True, "voltage", False)]
    assert f"| yes | voltage | no | {braced['hand_rms_error_m']:.4g} | {braced['hand_max_error_m']:.4g} |" in report

    # Passive (make run's: bracing-pair --no-bracing, the floor an obstacle) beside braced and free,
    # each number that of a direct in-process run of make run's passive parameters on the same engine.
    passive = {(s.varied["input_mode"], s.varied["gravity_compensation"]): rows[s.run_id] for s in study.passive}
    assert set(passive) == {(m, c) for m in ("voltage", "torque") for c in (False, True)}
    make_run = next(run for run in RUNS if run.name == "passive")
    shared = command_line(RunOptions(PAPER_YAML, tmp_path / "unused", mode="voltage", bracing=make_run.bracing))
    assert shared == {"input_mode": "voltage", "bracing": False}
    direct = summarize(run_recorded(build_scenario(PAPER_YAML, shared=shared), 2.5), wall_time_s=0.0)
    row = passive[("voltage", False)]
    assert row["bracing"] is False and row["contacts.elbow.normal_force_mean_n"] > 1.0  # the elbow rests on the floor
    for key in ("energy_consumed_j", "copper_loss_j", "hand_rms_error_m", "hand_max_error_m"):
        assert row[key] == pytest.approx(direct[key], rel=1e-9, abs=1e-12), key
    assert f"| passive | voltage | no | {row['hand_rms_error_m']:.4g} | {row['hand_max_error_m']:.4g} |" in report

    # The optimiser over the grid's two axes: its optimum meets the bound and uses no more energy than
    # the grid's best cell within it (its first trial is that cell: the same run, to 1e-9).
    assert search.found is not None and search.found.trials == 6 and search.found.search.failed == 0
    assert search.bound == PAPER_HAND_RMS_BOUND
    assert [(v.low, v.high) for v in search.problem.varies] == [(0.0, 40.0), (0.35, 0.85)]
    optimum = search.optimum
    assert optimum is not None and optimum["hand_rms_error_m"] <= PAPER_HAND_RMS_BOUND
    cells = [rows[s.run_id] for s in study.placement]
    within = [c for c in cells if c["hand_rms_error_m"] <= PAPER_HAND_RMS_BOUND]
    assert within
    best_cell = min(within, key=lambda c: c["energy_consumed_j"])
    assert optimum["energy_consumed_j"] <= best_cell["energy_consumed_j"]
    trials = open_study(search.problem, search.output).trials
    first = trials[0]
    assert first.params["contacts.elbow.desired_normal_force"] == best_cell["desired_normal_force"]
    assert first.params["contacts.elbow.target[1]"] == pytest.approx(best_cell["brace_target"], abs=1e-6)
    for key in ("energy_consumed_j", "hand_rms_error_m", "hand_max_error_m"):
        assert first.user_attrs["row"][key] == pytest.approx(best_cell[key], rel=1e-9, abs=1e-12), key
    best = search.found.best
    assert best is not None and f"| **optimum** (trial {best.number}) | {best.params[search.force]:.4g} |" in report
    assert f"{optimum['energy_consumed_j']:.4g} | {optimum['hand_rms_error_m']:.4g} |" in report
    setting, resting = by_case[(True, "voltage", False)], passive[("voltage", False)]
    cheaper = "less" if resting["energy_consumed_j"] < setting["energy_consumed_j"] else "more"
    said = f"**What the numbers say**: Resting passively uses {cheaper} energy than bracing at the paper's 10 N"
    assert said in report and report.count("**What the numbers say**") == 1
    assert "### The optimiser's answer" in report and "![energy and hand error" in report

    # The same study again reuses every run, and the optimiser's study: no new trial.
    with LocalExecutor(1) as executor:
        again = run_sweep(study.specs, tmp_path, executor, progress=False)
        assert again.ran == 0 and again.skipped == 24
        rerun = run_placement_search(placement_search(study, stored, tmp_path), executor, trials=6, progress=False)
    assert rerun.found is not None and rerun.found.search.ran == 0 and rerun.found.trials == 6
    assert rerun.found.best is not None and rerun.found.best.number == best.number
    assert len(open_study(search.problem, search.output).trials) == 6


def test_study_overrides_apply_to_every_run_of_each_node() -> None:
    study = build_study(PAPER_YAML, base={"gravity_compensation": True, "step": 0.002}, positions=1)
    assert len(study.placement) == 3  # one target (the start), three forces
    for spec in study.specs:
        # Comparison 1 varies the compensation itself; every other run takes the override.
        compensation = spec.varied.get("gravity_compensation", True)
        assert spec.ctl_params["gravity_compensation"] is compensation and "step" not in spec.ctl_params
        assert spec.sim_params["step"] == 0.002 and "gravity_compensation" not in spec.sim_params
    with pytest.raises(ConfigError, match=r"hand\.kp"):
        build_study(PAPER_YAML, base={"hand.kp": [1.0]})
