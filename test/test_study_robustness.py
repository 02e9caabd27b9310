"""bracing-study robustness: the paper scenario braced, passive and free under model error, real
sensing and command latency, one factor at a time, with the paper's law and with force feedback + thermal
compensation; one report with a table and a figure per factor and one generated paragraph. Short runs (the
full study's numbers are in docs/results/index.md); the nominal braced run is the plain paper run, bit for bit."""

from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq
import pytest

from bracing_core.numbers import cell as fmt
from bracing_experiments.executors import LocalExecutor
from bracing_experiments.experiment import STATUS_FAILED, STATUS_OK, execute_run
from bracing_experiments.robustness import (
    BRACED,
    FEEDBACK_GAINS,
    FEEDBACK_LAW,
    FORCE_LATE,
    FREE_SPACE,
    LAW_TEXT,
    NOMINAL_LEVEL,
    PAPER_LAW,
    PASSIVE,
    VARIANTS,
    build_robustness,
    late_force_rms,
    write_report,
)
from bracing_experiments.running import RESULTS_PARQUET, ResultsStore, run_sweep
from bracing_experiments.specs import make_spec
from bracing_experiments.study import main as study_main

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER_YAML = REPO_ROOT / "config" / "paper_4link.yaml"
FACTORS = ("mass", "friction", "torque_constant", "resistance", "encoder", "force_sensor", "latency")
METRICS = ("hand_rms_error_m", "hand_max_error_m", "normal_force_rms_error_n", "energy_consumed_j", "copper_loss_j")
KNOBS_AT_DEFAULTS = {
    "plant_error.mass_scale": 1.0,
    "plant_error.friction_scale": 1.0,
    "plant_error.torque_constant_scale": 1.0,
    "plant_error.resistance_scale": 1.0,
    "plant_error.urdf": "",
    "sensors.noise_seed": 7,
    "sensors.encoder_counts_per_rev": 0,
    "sensors.position_noise_rad": 0.0,
    "sensors.velocity_filter_hz": 0.0,
    "sensors.force_noise_n": 0.0,
    "sensors.force_bias_n": 0.0,
    "sensors.current_noise_a": 0.0,
    "sensors.command_latency_steps": 0,
    "contacts.elbow.force_feedback.kp": 0.0,
    "contacts.elbow.force_feedback.ki": 0.0,
    "voltage_law.thermal_compensation": False,
}
"""Every knob of the study at its off value: the paper's run, bit for bit (the seed draws nothing)."""


def test_the_study_covers_every_factor_around_the_nominal(tmp_path: Path) -> None:
    duration = 2.5  # hand RMS counts from t = 2 s
    study = build_robustness(PAPER_YAML, duration, levels_per_factor=1)  # each factor's last level
    assert tuple(f.key for f in study.factors) == FACTORS and study.mode == "voltage" and study.braced == ["elbow"]
    levels = {f.key: f.levels[0].label for f in study.factors}
    assert levels == {
        "mass": "masses x1.3",
        "friction": "mu 0.3",
        "torque_constant": "K x1.1",
        "resistance": "R x1.1",
        "encoder": "1024 counts/rev",
        "force_sensor": "force noise 2 N, bias 0.5 N",
        "latency": "latency 5 ms",  # 5 steps of the paper's 1 ms
    }
    # (nominal + 7 levels) x 2 laws x {braced, passive, free}, and braced torque input for the nominal, masses, mu
    assert len(study.specs) == 8 * 2 * 3 + 3 * 2
    assert len({spec.run_id for spec in study.specs}) == len(study.specs)

    # Each run sets its level's knobs and its law's, nothing else: force feedback on the braced contact only
    # where there is a brace task, thermal compensation on every voltage-input run of the feedback law.
    plain = make_spec(PAPER_YAML, {}, duration)
    for case, spec in study.runs.items():
        feedback = case.law == FEEDBACK_LAW
        ctl, sim = spec.ctl_params, spec.sim_params
        gains = FEEDBACK_GAINS[case.mode] if feedback and case.variant == BRACED.name else (0.0, 0.0)
        assert tuple(ctl.get(f"contacts.elbow.force_feedback.{k}", 0.0) for k in ("kp", "ki")) == gains, case
        assert ctl.get("voltage_law.thermal_compensation", False) is (feedback and case.mode == "voltage"), case
        assert spec.varied["input_mode"] == case.mode == ctl["input_mode"]
        if case.factor == "latency":
            assert sim["sensors.command_latency_steps"] == 5
    nominal = study.spec(None, NOMINAL_LEVEL, PAPER_LAW, BRACED.name)
    assert (nominal.sim_params, nominal.ctl_params) == (plain.sim_params, plain.ctl_params)

    with LocalExecutor(2) as executor:
        result = run_sweep(study.specs, tmp_path, executor, progress=False)
    assert result.ran == len(study.specs) and result.failed == 0 and not result.lost
    report = write_report(study, tmp_path, result.wall_time_s, "test").read_text()
    rows = {row["run_id"]: row for row in pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist()}
    assert all(row["status"] == STATUS_OK for row in rows.values())

    # A section, a table and a figure per factor, its rows for each level, law and variant.
    for k, factor in enumerate(study.factors, 1):
        assert f"## {k}. {factor.title}" in report
        assert f"](robustness_{factor.key}.png)" in report
        assert (tmp_path / f"robustness_{factor.key}.png").stat().st_size > 10_000
        of_factor = [row for row in rows.values() if row["factor"] == factor.key]
        assert len(of_factor) == 2 * 3 + (2 if factor.torque else 0)
        assert {(row["law"], row["variant"]) for row in of_factor} >= {
            (law, variant.name) for law in (PAPER_LAW, FEEDBACK_LAW) for variant in VARIANTS
        }
        for law in (PAPER_LAW, FEEDBACK_LAW):
            assert f"| {factor.levels[0].label} | {LAW_TEXT[law]} |" in report
    torque_tables = sum(1 for factor in study.factors if factor.torque)  # the torque rows' tables: masses, mu
    assert report.count(f"| nominal | {LAW_TEXT[PAPER_LAW]} |") == len(FACTORS) + torque_tables

    # The nominal braced run is the plain paper run's numbers exactly; so is a run with every knob set to
    # its off value (the defaults bit-identical); the table holds them.
    braced = rows[nominal.run_id]
    direct = execute_run(plain).row
    at_defaults = execute_run(make_spec(PAPER_YAML, {"knobs": "off"}, duration, overrides=KNOBS_AT_DEFAULTS)).row
    for key in METRICS:
        assert braced[key] == direct[key] == at_defaults[key], key
    assert f"| nominal | {LAW_TEXT[PAPER_LAW]} | {fmt(braced['hand_rms_error_m'])} |" in report
    passive = rows[study.spec(None, NOMINAL_LEVEL, PAPER_LAW, PASSIVE.name).run_id]
    free = rows[study.spec(None, NOMINAL_LEVEL, PAPER_LAW, FREE_SPACE.name).run_id]
    energy_ratio = braced["energy_consumed_j"] / free["energy_consumed_j"]
    assert energy_ratio < 0.5  # bracing's headline holds at the nominal
    assert f"| {fmt(braced['energy_consumed_j'])} | {fmt(passive['energy_consumed_j'])} |" in report
    assert f"| {fmt(energy_ratio)} |" in report

    # The force sensor is read by force feedback only: the paper's law runs exactly as at the nominal.
    sensor = study.factors[FACTORS.index("force_sensor")]
    sensed = study.row(rows, sensor, sensor.levels[0], PAPER_LAW, BRACED.name)
    assert sensed is not None and all(sensed[key] == braced[key] for key in METRICS)

    # With torque input, masses x1.3 in the plant: the paper's law misses f_nd, feedback brings it back.
    mass = study.factors[0]
    store = ResultsStore(tmp_path)
    paper, fed = (
        late_force_rms(store, study.row(rows, mass, mass.levels[0], law, BRACED.name, "torque"))
        for law in (PAPER_LAW, FEEDBACK_LAW)
    )
    assert paper is not None and fed is not None and fed < 0.1 * paper

    # One generated paragraph, from these numbers.
    question = "**Where does bracing still pay, and what does force feedback buy?** "
    assert report.count(question) == 1
    said = report.split(question)[1].split("\n")[0]
    assert said.startswith("Against free space, bracing pays (less energy and a more precise hand) in ")
    assert "Against resting passively" in said
    kp, ki = FEEDBACK_GAINS["voltage"]
    assert f"Force feedback (kp {kp:g}, ki {ki:g} /s) with thermal compensation takes the braced" in said
    assert f"after 2 s from {late_force_rms(store, braced):.3g} N" in said
    assert FORCE_LATE not in braced  # the report's column, not a stored one

    # The same study again runs nothing.
    with LocalExecutor(1) as executor:
        again = run_sweep(study.specs, tmp_path, executor, progress=False)
    assert again.ran == 0 and again.skipped == len(study.specs)


def test_bracing_study_robustness_runs_the_study_and_refuses_bad_arguments(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Configuration errors before any run: exit 2, nothing run.
    for bad in (["--set", "no_such_parameter=1"], ["--set", "plant_error.mass_scale=-1"]):
        output = tmp_path / "refused"
        assert study_main(["robustness", "--output", str(output), *bad]) == 2
        assert not (output / "runs").exists()
        assert "bracing-study robustness: error:" in capsys.readouterr().err
    for bad in (["--duration", "0"], ["--workers", "1", "--scheduler", "local"], ["--workers", "0"], []):
        with pytest.raises(SystemExit) as exit_:
            study_main(["robustness", *(["--output", str(tmp_path / "x")] if bad else []), *bad])
        assert exit_.value.code == 2, bad

    # The whole study in short runs (hand RMS needs t >= 2 s: n/a; the paragraph answers on energy).
    output = tmp_path / "study"
    assert (
        study_main(["robustness", "--output", str(output), "--duration", "0.3", "--workers", "1", "--no-progress"]) == 0
    )
    report = (output / "report.md").read_text()
    rows = pq.read_table(output / RESULTS_PARQUET).to_pylist()
    assert len(rows) == 19 * 2 * 3 + 8 * 2 and {row["factor"] for row in rows} == {"nominal", *FACTORS}
    assert "Against free space, bracing pays (less energy) in " in report
    assert "braced |f_n - f_nd| RMS over the run from" in report
    # Runs that end before the hand window opens: run, and the report says the hand is not judged.
    assert "runs of 0.3 s end before that window opens, so they are not measured here" in report
    assert len(list(output.glob("robustness_*.png"))) == len(FACTORS)

    # A run that fails: exit 1, the report still written, its cells say so.
    failing = tmp_path / "failing"
    args = ["robustness", "--output", str(failing), "--duration", "0.05", "--workers", "1", "--no-progress"]
    assert study_main([*args, "--set", "divergence_speed=0.01"]) == 1
    report = (failing / "report.md").read_text()
    assert "0 ok" in report and "| failed |" in report and "No run came back ok: no answer." in report
    assert all(row["status"] == STATUS_FAILED for row in pq.read_table(failing / RESULTS_PARQUET).to_pylist())
