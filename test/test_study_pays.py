"""bracing-study pays: braced against passive and free space over f_nd and the brace place, under realistic
conditions with several seeds, the optimiser's brace re-run on every seed; the report states where bracing
beats resting passively with its spread. Short runs (hand errors count from t = 2 s); the full study's
numbers are in docs/results/index.md, rendered from its recorded tables."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from bracing_experiments.pays_report import spread_text
from bracing_experiments.pays_specs import ENERGY, HAND_RMS, REALISTIC, build_pays, conditions
from bracing_experiments.recorded import TABLES_FILE, render_table
from bracing_experiments.study import main as study_main

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER_YAML = REPO_ROOT / "config" / "paper_4link.yaml"
UR5_YAML = REPO_ROOT / "config" / "ur5_table.yaml"
DURATION = "2.5"


def test_a_ratio_is_its_median_over_seeds_with_its_spread() -> None:
    assert spread_text([0.5]) == "0.5" and spread_text([0.5, 0.7, 0.6]) == "0.6 (0.5-0.7)" and spread_text([]) == "n/a"
    ten = [float(k) for k in range(1, 11)]  # 10 seeds: 10 % at 1.9, 90 % at 9.1 (linear interpolation)
    assert spread_text(ten, 2) == "5.5 (1.9-9.1)"


def test_each_seed_draws_its_own_conditions_and_the_same_seed_the_same() -> None:
    assert conditions(1) == conditions(1) and conditions(1) != conditions(2)
    for seed in (1, 2, 3):
        drawn = conditions(seed)
        assert drawn["sensors.noise_seed"] == seed and 0.9 <= drawn["plant_error.mass_scale"] <= 1.1
        assert {key: drawn[key] for key in REALISTIC} == REALISTIC


def test_the_grid_on_the_paper_arm_and_on_the_ur5() -> None:
    paper = build_pays(PAPER_YAML, 2, 2.5, forces=[10.0, 20.0], positions=3, span=0.1)
    assert paper.places == [
        pytest.approx(0.487785, abs=1e-6),
        pytest.approx(0.587785, abs=1e-6),
        pytest.approx(0.687785, abs=1e-6),
    ]
    assert len(paper.specs) == 2 * (3 + 2 * 3)  # per seed: passive, free, the file's brace, the grid
    assert len({spec.run_id for spec in paper.specs}) == len(paper.specs)
    ur5 = build_pays(UR5_YAML, 1, 2.5)  # a brace without a brace axis: f_nd only, at the file's place
    assert ur5.places == [None] and ur5.forces == [5.0, 10.0, 20.0, 30.0]
    assert len(ur5.specs) == 3 + 4


def _run(output: Path, *extra: str) -> int:
    args = ["pays", "--output", str(output), "--duration", DURATION, "--workers", "1", "--no-progress"]
    return study_main([*args, *extra])


def test_the_study_says_where_bracing_pays_with_its_spread(tmp_path: Path) -> None:
    out = tmp_path / "pays"
    grid = ("--forces", "10,25", "--positions", "2", "--span", "0.15", "--seeds", "3", "--trials", "4")
    assert _run(out, *grid) == 0
    runs = pq.read_table(out / "runs.parquet").to_pylist()
    assert (out / "runs.csv").read_text().count("\n") == len(runs) + 1  # a header and a row per run
    assert all(run["status"] == "ok" for run in runs)
    per_seed = Counter(run["seed"] for run in runs)
    assert per_seed == {1: 8, 2: 8, 3: 8}  # passive, free, the file's brace, 2 x 2 cells, the optimum's re-run

    passive = {run["seed"]: run for run in runs if run["condition"] == "passive"}
    assert len({run[ENERGY] for run in passive.values()}) == 3  # each seed its own noise and plant
    report = (out / "report.md").read_text()
    # Every ratio in the table is braced / passive of the same seed, median (range) over the three.
    braced = [run for run in runs if run["condition"] == "grid"]
    for force, place in sorted({(run["f_nd"], run["place"]) for run in braced}):
        cell = {run["seed"]: run for run in braced if (run["f_nd"], run["place"]) == (force, place)}
        energy = [cell[seed][ENERGY] / passive[seed][ENERGY] for seed in (1, 2, 3)]
        hand = [cell[seed][HAND_RMS] / passive[seed][HAND_RMS] for seed in (1, 2, 3)]
        pays = sum(1 for e, h in zip(energy, hand, strict=True) if e < 1 and h < 1)
        line = f"| grid | {force:.4g} | {place:.4g} | 3/3 | {spread_text(energy)} | {spread_text(hand)} |"
        assert line in report, line
        counts = f"{sum(1 for e in energy if e < 1)}/3 | {sum(1 for h in hand if h < 1)}/3 | {pays}/3"
        both = f"{spread_text(hand)} | {counts} |"
        assert both in report, both
    assert "**When bracing pays** (against resting passively" in report
    assert "in all 3 seeds" in report and "optimiser's brace" in report

    # The recorded tables are the report's, byte for byte; the same command again runs nothing new.
    recorded = json.loads((out / TABLES_FILE).read_text())
    assert recorded["study"] == "pays" and recorded["config"] == "paper_4link.yaml"
    for table in recorded["tables"].values():
        assert render_table(table) in report
    again = tmp_path / "again"
    assert _run(again, *grid[:-2], "--trials", "0") == 0
    first = {run["run_id"]: run for run in runs}
    rerun = pq.read_table(again / "runs.parquet").to_pylist()
    assert len(rerun) == 3 * 7
    for run in rerun:  # the same seed: the same run, bit for bit
        assert (run[ENERGY], run[HAND_RMS]) == (first[run["run_id"]][ENERGY], first[run["run_id"]][HAND_RMS])


def test_the_ur5_varies_the_force_at_its_place(tmp_path: Path) -> None:
    out = tmp_path / "ur5"
    assert _run(out, "--config", str(UR5_YAML), "--forces", "10", "--trials", "0") == 0
    runs = pq.read_table(out / "runs.parquet").to_pylist()
    assert sorted(run["condition"] for run in runs) == ["file", "free", "grid", "passive"]
    assert all(run["status"] == "ok" for run in runs)
    report = (out / "report.md").read_text()
    assert "the file's (no brace axis)" in report and "Not run (--trials 0)." in report


def test_bad_arguments_are_refused_before_any_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(tmp_path / "a", "--forces", "10,-1") == 2
    assert "--forces" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        _run(tmp_path / "b", "--seeds", "0")
    assert exit_.value.code == 2
    args = ["pays", "--output", str(tmp_path / "c"), "--duration", "2", "--workers", "1"]
    assert study_main(args) == 2  # hand errors count from t = 2 s: a 2 s run has none to compare
    assert "--duration 2" in capsys.readouterr().err
    assert _run(tmp_path / "d", "--set", "sensors.noise_seed=3") == 2
    assert "--seeds" in capsys.readouterr().err
    assert not (tmp_path / "a" / "runs.csv").exists() and not (tmp_path / "c" / "runs.csv").exists()
