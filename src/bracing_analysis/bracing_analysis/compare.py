"""Several recorded runs side by side: ``bracing-report BAG1 BAG2 ... --compare [--baseline NAME] [--output DIR]``.

Writes ``compare_hand_error.png``, ``compare_brace_error.png``, ``compare_normal_force.png``,
``compare_energy.png`` (one line per run over time) and ``compare.md`` (the summary table
in Markdown, one column per run, then each other run divided by the baseline run). A run is
named after its directory (``out/braced/bag`` -> ``braced``); the baseline is ``--baseline NAME``,
by default the first run. A figure that no run has data for is not written; a run that a figure's
metric does not apply to is listed in its legend as n/a.

A ratio is n/a where it would mislead (``ratios``): energies of runs with different input modes
(voltage input books electrical joules, torque input the joints' mechanical work), and any metric
whose baseline value is ~0 (a torque-input force error of 5e-14 N is 0).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bracing_analysis.bag import read_series, resolve_bag
from bracing_analysis.ratios import RATIO_FLOOR, ratio_text
from bracing_analysis.series import BagSeries, scenario_name
from bracing_analysis.summary import SUMMARY_KEYS, compute_summary, heading
from bracing_core.contact_roles import BRACED, by_role
from bracing_core.numbers import cell, markdown_table, number

if TYPE_CHECKING:
    from matplotlib.figure import Figure

COMPARE_MD = "compare.md"

TABLE_KEYS = (*SUMMARY_KEYS, "max_penetration_m", "input_mode", "bracing")
"""compare.md's rows: summary.json's single values (each run's summary.json has the per-contact ones)."""

TEXT_KEYS = frozenset({"input_mode", "bracing"})
"""Rows of names, not numbers: no ratio."""


class BaselineError(ValueError):
    """--baseline names no run of the comparison."""


def run_labels(bags: Sequence[str | Path]) -> list[str]:
    """Each run's directory name (the parent of its bag); the full path where names repeat."""
    dirs = [resolve_bag(Path(b)).resolve().parent for b in bags]
    names = [d.name for d in dirs]
    if len(set(names)) == len(names):
        return names
    return [str(d) for d in dirs]


def _stored_wall_time(bag: Path) -> float | None:
    """wall_time_s of the run's summary.json (the report cannot know it from the bag)."""
    try:
        value = json.loads((resolve_bag(bag).resolve().parent / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    wall = value.get("wall_time_s") if isinstance(value, dict) else None
    return float(wall) if number(wall) else None


def baseline_index(labels: Sequence[str], baseline: str | None) -> int:
    """Where the run named ``baseline`` is (None: the first run)."""
    if baseline is None:
        return 0
    if baseline not in labels:
        raise BaselineError(f"--baseline {baseline!r}: no such run (the runs: {', '.join(labels)})")
    return list(labels).index(baseline)


def comparison_table(labels: Sequence[str], summaries: Sequence[dict[str, Any]], baseline: int = 0) -> str:
    """The summaries as a Markdown table: a row per metric, a column per run, and each other run's
    ratio to the run ``baseline`` (an index of ``labels``)."""
    head = ["metric", *labels]
    others = [k for k in range(len(labels)) if k != baseline]
    head += [f"{labels[k]} / {labels[baseline]}" for k in others]
    rows = []
    for key in TABLE_KEYS:
        label, unit = heading(key)
        cells = [f"{label} [{unit}]" if unit else label]
        cells += [cell(s.get(key), bools=("True", "False")) for s in summaries]
        for k in others:  # a ratio of names (input mode, bracing) means nothing: left empty
            cells.append("" if key in TEXT_KEYS else ratio_text(key, summaries[k], summaries[baseline]))
        rows.append(cells)
    return markdown_table(head, rows) + "\n"


def hand_error(series: BagSeries) -> np.ndarray:
    """|r_dh - r_h| [m] at the controller_state stamps."""
    return np.linalg.norm(series.hand_desired - series.hand_actual, axis=1)


def _scenarios(runs: Sequence[tuple[str, BagSeries]]) -> str:
    return ", ".join(dict.fromkeys(scenario_name(s) for _, s in runs))


def _not_applicable(ax: Any, label: str, why: str) -> None:
    """A legend entry (and no line) for a run that the figure's metric does not apply to."""
    ax.plot([], [], " ", label=f"{label}: n/a ({why})")


def comparison_figures(runs: Sequence[tuple[str, BagSeries]]) -> dict[str, Figure]:
    """The comparison figures the data allows, by file name (without .png)."""
    from bracing_analysis.figures import figure  # matplotlib (~0.8 s): only when drawing

    figures: dict[str, Figure] = {}
    scenarios = _scenarios(runs)
    if any(s.t.size for _, s in runs):
        fig, ax = figure(f"{scenarios}: hand tracking error", "|r_dh - r_h| [m]")
        for label, s in runs:
            if s.t.size:
                ax.plot(s.t, hand_error(s), label=label)
            else:
                _not_applicable(ax, label, "no controller state")
        figures["compare_hand_error"] = fig
    if any(cs.t_ctrl.size for _, s in runs for cs in s.contacts.values()):
        fig, ax = figure(f"{scenarios}: brace point error", "|r_dj - r_j| [m]")
        for label, s in runs:
            braced = [cs for cs in s.contacts.values() if cs.t_ctrl.size]
            for cs in braced:
                error = np.linalg.norm(cs.brace_desired - cs.brace_actual, axis=1)
                ax.plot(cs.t_ctrl, error, label=f"{label}: {cs.name}")
            if not braced:
                _not_applicable(ax, label, "no brace task")
        figures["compare_brace_error"] = fig
    if any(cs.t.size for _, s in runs for cs in s.contacts.values()):
        fig, ax = figure(f"{scenarios}: normal (reaction) forces at the contacts", "f_n [N]")
        for label, s in runs:
            touching = [cs for cs in by_role(s.contacts, BRACED).values() if cs.t.size]  # kept-out ones: the report's
            for cs in touching:
                (line,) = ax.plot(cs.t, cs.normal_force, label=f"{label}: {cs.name} f_n")
                if cs.t_ctrl.size:
                    ax.plot(
                        cs.t_ctrl,
                        cs.normal_force_desired,
                        "--",
                        color=line.get_color(),
                        lw=1.0,
                        label=f"{label}: {cs.name} f_nd",
                    )
            if not touching:
                _not_applicable(ax, label, "no contacts")
        figures["compare_normal_force"] = fig
    if any(s.motor_t.size for _, s in runs):
        figures["compare_energy"] = _energy_figure(runs, scenarios)
    for fig in figures.values():
        for ax in fig.axes:
            if ax.get_legend_handles_labels()[0]:
                ax.legend(loc="best")
    return figures


def plot_comparison(runs: Sequence[tuple[str, BagSeries]], out: Path) -> list[Path]:
    """The comparison figures the data allows (``comparison_figures``); the files written."""
    written = []
    for name, fig in comparison_figures(runs).items():
        fig.savefig(out / f"{name}.png", dpi=120)
        written.append(out / f"{name}.png")
    return written


ENERGY_KINDS = {
    "voltage": ("electrical energy consumed by the motors", "∫ Σ|v i| dt [J]"),
    "torque": ("mechanical energy of the joint drives (torque input)", "∫ Σ|τ dq| dt [J]"),
}


def _energy_figure(runs: Sequence[tuple[str, BagSeries]], scenarios: str) -> Figure:
    """Energy over time, one axes per input mode: electrical and mechanical joules are not one quantity."""
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    modes = list(dict.fromkeys(s.input_mode or "unknown" for _, s in runs if s.motor_t.size))
    fig = Figure(figsize=(7.0, 4.2 * len(modes)), layout="constrained")
    for ax, mode in zip(np.atleast_1d(fig.subplots(len(modes), 1)), modes, strict=True):
        what, unit = ENERGY_KINDS.get(mode, ("energy consumed", "[J]"))
        ax.set_title(f"{scenarios}: {what}")
        ax.set_xlabel("time t [s]")
        ax.set_ylabel(unit)
        ax.grid(True, alpha=0.4)
        for label, s in runs:
            if s.motor_t.size and (s.input_mode or "unknown") == mode:
                ax.plot(s.motor_t, s.energy_consumed, label=label)
    return fig


def default_compare_dir(bags: Sequence[str | Path]) -> Path:
    """The directory that holds every run (``out`` for out/braced/bag and out/free_space/bag)."""
    return Path(os.path.commonpath([str(resolve_bag(Path(b)).resolve().parent) for b in bags]))


def write_comparison(
    bags: Sequence[str | Path],
    output_dir: str | Path | None = None,
    labels: Sequence[str] | None = None,
    baseline: str | None = None,
    series: Sequence[BagSeries] | None = None,
) -> list[Path]:
    """Read every bag, write the comparison figures and compare.md; the files written.

    ``baseline``: the run (by label) the others are divided by; default the first. ``series``: each bag's,
    read already (make run's reports read them: a second read of its three 10 s bags took 0.6 s); None: read here.
    Raises summary.BagReadError for an unreadable bag, BaselineError for a baseline that is no run.
    """
    names = list(labels) if labels is not None else run_labels(bags)
    base = baseline_index(names, baseline)
    out = Path(output_dir) if output_dir is not None else default_compare_dir(bags)
    out.mkdir(parents=True, exist_ok=True)
    read = list(series) if series is not None else [read_series(bag) for bag in bags]
    runs = list(zip(names, read, strict=True))
    summaries = [compute_summary(s, _stored_wall_time(Path(bag))) for (_, s), bag in zip(runs, bags, strict=True)]
    written = plot_comparison(runs, out)
    md = out / COMPARE_MD
    sources = "\n".join(f"- `{name}`: `{bag}`" for name, bag in zip(names, bags, strict=True))
    md.write_text(
        "# Runs compared\n\n"
        + sources
        + f"\n\nRatios: each run / `{names[base]}` (the baseline; `--baseline NAME` chooses it). Energies only "
        "between runs of one input mode (voltage input: electrical joules; torque input: the joints' mechanical "
        f"work); n/a where the baseline is ~0 (below {RATIO_FLOOR:g}) or a metric does not apply.\n\n"
        + comparison_table(names, summaries, base)
        + "\nFigures: "
        + ", ".join(f"`{p.name}`" for p in written)
        + "\n",
        encoding="utf-8",
    )
    written.append(md)
    return written
