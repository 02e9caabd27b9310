"""What does not apply is null in summary.json and n/a in every table, figure and
comparison; titles name the scenario and cite the paper only for the paper's; comparisons divide by
a stated baseline, never across input modes for energy, never by ~0.

Series and bags built here (the numbers known exactly), and the two short recorded runs of the
``runs`` fixture (conftest: a real bracing-pair over DDS, braced and with no contacts).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_recorder_report import N_STEPS, PAPER_URDF, write_bag_directly

from bracing_analysis.bag import read_series
from bracing_analysis.compare import comparison_figures, comparison_table
from bracing_analysis.figures import plot_figure, title
from bracing_analysis.ratios import RATIO_FLOOR, ratio_text
from bracing_analysis.report import main as report_main
from bracing_analysis.series import BagSeries, ContactSeries
from bracing_analysis.summary import compute_summary
from bracing_bringup.paper_run import table

DT = 0.01


def _series(mode: str, braced: bool, touching: bool) -> BagSeries:
    """3 s of a run: a hand 1 cm off its target, energy 0.5 J/s, copper loss 0.2 J/s; one contact,
    braced or an obstacle, touching its surface throughout or never."""
    t = np.arange(301) * DT
    series = BagSeries(joint_t=t, t=t, motor_t=t, input_mode=mode)
    series.hand_desired = np.zeros((t.size, 3))
    series.hand_actual = np.tile([0.0, 0.01, 0.0], (t.size, 1))
    series.energy_consumed, series.copper_loss = 0.5 * t, 0.2 * t
    contact = ContactSeries(name="elbow", t=t, active=np.full(t.size, touching), residual=np.full(t.size, 1e-12))
    contact.normal_force = np.full(t.size, 10.0 if touching else 0.0)
    contact.slip_velocity = np.zeros((t.size, 3))
    if braced:
        contact.t_ctrl = contact.t_matched = t
        contact.normal_force_desired = np.full(t.size, 10.0)
        contact.normal_force_error = contact.normal_force - 10.0
        contact.brace_desired = np.zeros((t.size, 3))
        contact.brace_actual = np.tile([0.0, 0.002, 0.0], (t.size, 1))
    series.contacts = {"elbow": contact}
    return series


# --------------------------------------------------------------------------- summary.json


def test_run_totals_are_null_where_the_metric_does_not_apply() -> None:
    braced = compute_summary(_series("voltage", braced=True, touching=True))
    assert braced["brace_rms_error_m"] == pytest.approx(0.002)
    assert braced["normal_force_rms_error_n"] == 0.0  # applies, and is exactly 0
    assert braced["copper_loss_j"] == pytest.approx(0.6)
    assert braced["constraint_residual_max_m"] == pytest.approx(1e-12)

    # No brace task, torque input, the obstacle never touched: nothing of those applies.
    passive = compute_summary(_series("torque", braced=False, touching=False))
    for key in ("brace_rms_error_m", "normal_force_rms_error_n", "copper_loss_j", "constraint_residual_max_m"):
        assert passive[key] is None, key
    assert passive["energy_consumed_j"] == pytest.approx(1.5)  # mechanical joules: they apply
    assert passive["contacts"]["elbow"]["brace_rms_error_m"] is None  # the top level agrees with the contact
    assert passive["warnings"] == []
    assert "null" in json.dumps(passive, allow_nan=False)


def test_the_recorded_run_without_contacts_says_null_not_zero(runs: dict[str, Path]) -> None:
    """A real bracing-pair run (no contacts at all): its summary.json has null totals, and a
    comparison with the braced run shows n/a for them and in the brace figure's legend."""
    unbraced = json.loads((runs["unbraced"] / "summary.json").read_text())
    for key in ("brace_rms_error_m", "normal_force_rms_error_n", "constraint_residual_max_m", "max_penetration_m"):
        assert unbraced[key] is None, key
    braced = json.loads((runs["braced"] / "summary.json").read_text())
    assert isinstance(braced["brace_rms_error_m"], float) and braced["brace_rms_error_m"] > 0.0
    markdown = comparison_table(["braced", "unbraced"], [braced, unbraced])
    brace_row = next(line for line in markdown.splitlines() if line.startswith("| brace RMS error"))
    assert [c.strip() for c in brace_row.strip("|").split("|")][2:] == ["n/a", "n/a"]

    runs_read = [(name, read_series(runs[name] / "bag")) for name in ("braced", "unbraced")]
    figures = comparison_figures(runs_read)
    labels = figures["compare_brace_error"].axes[0].get_legend_handles_labels()[1]
    assert "unbraced: n/a (no brace task)" in labels and "braced: elbow" in labels
    brace_lines = [line for line in figures["compare_brace_error"].axes[0].lines if len(line.get_xdata())]
    assert len(brace_lines) == 1  # no flat line for the run with no brace task


# --------------------------------------------------------------------------- ratios


def _summary(mode: str, energy: float, force: float, hand: float) -> dict[str, Any]:
    return {
        "input_mode": mode,
        "energy_consumed_j": energy,
        "copper_loss_j": energy / 2 if mode == "voltage" else None,
        "normal_force_rms_error_n": force,
        "hand_rms_error_m": hand,
        "bracing": True,
    }


def _row(markdown: str, start: str) -> list[str]:
    line = next(line for line in markdown.splitlines() if line.startswith(f"| {start}"))
    return [cell.strip() for cell in line.strip("|").split("|")]


def test_comparison_divides_by_the_stated_baseline_never_by_zero_nor_across_input_modes() -> None:
    labels = ["volt", "free", "torque"]
    summaries = [
        _summary("voltage", 3000.0, 2.0, 0.05),
        _summary("voltage", 10000.0, 4.0, 0.1),
        _summary("torque", 18.0, 5e-14, 0.04),  # eq. 40: f_n = f_nd to machine precision
    ]
    by_free = comparison_table(labels, summaries, baseline=1)
    assert by_free.splitlines()[0] == "| metric | volt | free | torque | volt / free | torque / free |"
    assert _row(by_free, "energy consumed")[4:] == ["0.300", "n/a (torque vs voltage input)"]
    assert _row(by_free, "copper loss")[3:] == ["n/a", "0.300", "n/a"]  # torque input has none
    assert _row(by_free, "hand RMS error")[4:] == ["0.500", "0.400"]
    assert _row(by_free, "input mode")[4:] == ["", ""]  # names have no ratio

    by_torque = comparison_table(labels, summaries, baseline=2)
    assert _row(by_torque, "normal force RMS error")[4:] == ["n/a (baseline ~0)", "n/a (baseline ~0)"]
    assert ratio_text("normal_force_rms_error_n", summaries[2], summaries[0]) == "0.000"  # ~0 on top is fine
    assert 5e-14 < RATIO_FLOOR < 1e-3

    # make run's table: the same rules.
    text = table({"braced": summaries[2], "passive": summaries[1], "free_space": summaries[0]})
    assert "energy ratio braced / free space: n/a (torque vs voltage input)" in text
    assert "hand RMS error ratio braced / free space: 0.800" in text


def test_bracing_report_compare_takes_a_baseline(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bags = []
    for name in ("first", "second"):
        write_bag_directly(tmp_path / name / "bag", N_STEPS, ("elbow",))
        bags.append(str(tmp_path / name / "bag"))
    assert report_main([*bags, "--compare", "--output", str(tmp_path / "default")]) == 0
    default = (tmp_path / "default" / "compare.md").read_text()
    assert "| metric | first | second | second / first |" in default  # the first run by default
    assert "each run / `first` (the baseline" in default
    assert report_main([*bags, "--compare", "--baseline", "second", "--output", str(tmp_path / "by_second")]) == 0
    assert "| metric | first | second | first / second |" in (tmp_path / "by_second" / "compare.md").read_text()
    capsys.readouterr()
    assert report_main([*bags, "--compare", "--baseline", "third", "--output", str(tmp_path / "x")]) == 2
    assert "--baseline 'third': no such run (the runs: first, second)" in capsys.readouterr().err


# --------------------------------------------------------------------------- figures


def test_titles_name_the_scenario_and_cite_the_paper_only_for_it(tmp_path: Path) -> None:
    write_bag_directly(tmp_path / "bag", N_STEPS, ("elbow",))
    series = read_series(tmp_path / "bag")
    assert series.scenario is None  # a bag that does not say
    series.robot_description = PAPER_URDF.read_text()
    assert plot_figure("hand_y", series).axes[0].get_title() == "robot paper_4link: hand y position"
    series.scenario = "hyper_7link"
    for name in ("hand_y", "hand_z", "brace_z", "normal_force", "energy"):
        text = plot_figure(name, series).axes[0].get_title()
        assert text.startswith("hyper_7link: ") and "paper" not in text, text
    series.scenario = "paper_4link"
    assert plot_figure("hand_y", series).axes[0].get_title() == "paper_4link: hand y position (paper Figs. 6, 9, 13)"
    assert title(series, "electrical energy of the motors", "Fig. 8").endswith("(paper Fig. 8)")


def test_the_recorded_paper_run_knows_its_scenario(runs: dict[str, Path]) -> None:
    series = read_series(runs["braced"] / "bag")
    assert series.scenario == "paper_4link"  # bracing-pair tells the recorder, which keeps it in the bag
    assert plot_figure("normal_force", series).axes[0].get_title().endswith("(paper Figs. 12, 16)")


def test_energy_of_torque_input_is_mechanical_with_no_copper_loss() -> None:
    torque = _series("torque", braced=True, touching=True)
    axes = plot_figure("energy", torque).axes[0]
    assert "mechanical energy" in axes.get_title()
    labels = axes.get_legend_handles_labels()[1]
    assert "copper loss: n/a (torque input: no motor circuit)" in labels
    assert not any("R i²" in label for label in labels)

    voltage = _series("voltage", braced=True, touching=True)
    figures = comparison_figures([("volt", voltage), ("torque", torque)])
    energy = figures["compare_energy"].axes
    assert len(energy) == 2  # electrical and mechanical joules on axes of their own
    assert "electrical" in energy[0].get_title() and "mechanical" in energy[1].get_title()
    assert [energy[0].get_legend_handles_labels()[1], energy[1].get_legend_handles_labels()[1]] == [
        ["volt"],
        ["torque"],
    ]
