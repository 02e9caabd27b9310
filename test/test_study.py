"""bracing-study: the paper's three comparisons in one report (short runs: the claims that hold from
the first seconds on; the full 10 s study is in the README)."""

from __future__ import annotations

import re
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from bracing_bringup.executors import LocalExecutor
from bracing_bringup.experiment import FORCE_MAX_ERROR_KEY, STATUS_OK
from bracing_bringup.study import build_study, resolve_scenario, write_report
from bracing_bringup.sweep import RESULTS_PARQUET, run_sweep
from bracing_core.params import ConfigError

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
    assert (len(study.bracing), len(study.gains), len(study.placement)) == (8, 8, 4)
    assert study.contact == "elbow" and study.axis == "y"
    assert study.targets == pytest.approx([0.5878 - 0.1, 0.5878 + 0.1], abs=1e-4)  # the elbow starts at y = 0.5878
    assert study.forces == [10.0, 20.0]
    with LocalExecutor(2) as executor:
        result = run_sweep(study.specs, tmp_path, executor, progress=False)
    assert result.ran == 20 and result.failed == 0
    report = write_report(study, tmp_path, result.wall_time_s, "test").read_text()
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

    # The same study again reuses every run.
    with LocalExecutor(1) as executor:
        again = run_sweep(study.specs, tmp_path, executor, progress=False)
    assert again.ran == 0 and again.skipped == 20


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
