"""Several recorded runs side by side: ``bracing-report BAG1 BAG2 ... --compare [--output DIR]``.

Writes ``compare_hand_error.png``, ``compare_brace_error.png``, ``compare_normal_force.png``,
``compare_energy.png`` (one line per run over time) and ``compare.md`` (the summary table
in Markdown, one column per run). A run is named after its directory (``out/braced/bag``
-> ``braced``). A figure that no run has data for is not written.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bracing_bringup.summary import SUMMARY_KEYS, BagSeries, compute_summary, read_series, resolve_bag

COMPARE_MD = "compare.md"

ROWS: dict[str, tuple[str, str]] = {
    "hand_rms_error_m": ("hand RMS error (t >= 2 s)", "m"),
    "hand_max_error_m": ("hand max error (t >= 2 s)", "m"),
    "brace_rms_error_m": ("brace RMS error", "m"),
    "normal_force_rms_error_n": ("normal force RMS error", "N"),
    "energy_consumed_j": ("energy consumed", "J"),
    "copper_loss_j": ("copper loss", "J"),
    "constraint_residual_max_m": ("max constraint residual", "m"),
    "sim_time_s": ("sim time", "s"),
    "wall_time_s": ("wall time", "s"),
    "real_time_factor": ("real-time factor", ""),
    "max_penetration_m": ("max penetration", "m"),
    "input_mode": ("input mode", ""),
    "bracing": ("bracing", ""),
}
TABLE_KEYS = (*SUMMARY_KEYS, "max_penetration_m", "input_mode", "bracing")
"""compare.md's rows: summary.json's single values (each run's summary.json has the per-contact ones)."""


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
    return float(wall) if isinstance(wall, (int, float)) and not isinstance(wall, bool) else None


def _cell(value: Any) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def markdown_table(labels: Sequence[str], summaries: Sequence[dict[str, Any]]) -> str:
    """The summaries as a Markdown table: a row per metric, a column per run, and ratios to the last run."""
    head = ["metric", *labels]
    ratio = len(labels) > 1
    if ratio:
        head += [f"{label} / {labels[-1]}" for label in labels[:-1]]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for key in TABLE_KEYS:
        label, unit = ROWS.get(key, (key, ""))
        cells = [f"{label} [{unit}]" if unit else label] + [_cell(s.get(key)) for s in summaries]
        if ratio:
            last = summaries[-1].get(key)
            for s in summaries[:-1]:
                value = s.get(key)
                ok = _number(value) and _number(last) and last
                cells.append(f"{value / last:.3f}" if ok else "n/a")  # type: ignore[operator]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def hand_error(series: BagSeries) -> np.ndarray:
    """|r_dh - r_h| [m] at the controller_state stamps."""
    return np.linalg.norm(series.hand_desired - series.hand_actual, axis=1)


def plot_comparison(runs: Sequence[tuple[str, BagSeries]], out: Path) -> list[Path]:
    """The comparison figures the data allows; the files written."""
    from bracing_bringup.report import figure, save_figure  # matplotlib: only when drawing

    written: list[Path] = []
    if any(s.t.size for _, s in runs):
        fig, ax = figure("Hand tracking error", "|r_dh - r_h| [m]")
        for label, s in runs:
            if s.t.size:
                ax.plot(s.t, hand_error(s), label=label)
        written.append(save_figure(fig, ax, out / "compare_hand_error.png"))
    if any(cs.t_ctrl.size for _, s in runs for cs in s.contacts.values()):
        fig, ax = figure("Brace point error", "|r_dj - r_j| [m]")
        for label, s in runs:
            for cs in s.contacts.values():
                if cs.t_ctrl.size:
                    error = np.linalg.norm(cs.brace_desired - cs.brace_actual, axis=1)
                    ax.plot(cs.t_ctrl, error, label=f"{label}: {cs.name}")
        written.append(save_figure(fig, ax, out / "compare_brace_error.png"))
    if any(cs.t.size for _, s in runs for cs in s.contacts.values()):
        fig, ax = figure("Normal (reaction) force at the braces", "f_n [N]")
        for label, s in runs:
            for cs in s.contacts.values():
                if cs.t.size:
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
        written.append(save_figure(fig, ax, out / "compare_normal_force.png"))
    if any(s.motor_t.size for _, s in runs):
        fig, ax = figure("Electrical energy consumed by the motors", "∫ Σ|v i| dt [J]")
        for label, s in runs:
            if s.motor_t.size:
                ax.plot(s.motor_t, s.energy_consumed, label=label)
        written.append(save_figure(fig, ax, out / "compare_energy.png"))
    return written


def default_compare_dir(bags: Sequence[str | Path]) -> Path:
    """The directory that holds every run (``out`` for out/braced/bag and out/free_space/bag)."""
    return Path(os.path.commonpath([str(resolve_bag(Path(b)).resolve().parent) for b in bags]))


def write_comparison(
    bags: Sequence[str | Path], output_dir: str | Path | None = None, labels: Sequence[str] | None = None
) -> list[Path]:
    """Read every bag, write the comparison figures and compare.md; the files written.

    Raises summary.BagReadError for an unreadable bag.
    """
    names = list(labels) if labels is not None else run_labels(bags)
    out = Path(output_dir) if output_dir is not None else default_compare_dir(bags)
    out.mkdir(parents=True, exist_ok=True)
    runs = [(name, read_series(bag)) for name, bag in zip(names, bags, strict=True)]
    summaries = [compute_summary(s, _stored_wall_time(Path(bag))) for (_, s), bag in zip(runs, bags, strict=True)]
    written = plot_comparison(runs, out)
    md = out / COMPARE_MD
    sources = "\n".join(f"- `{name}`: `{bag}`" for name, bag in zip(names, bags, strict=True))
    md.write_text(
        "# Runs compared\n\n"
        + sources
        + "\n\n"
        + markdown_table(names, summaries)
        + "\nFigures: "
        + ", ".join(f"`{p.name}`" for p in written)
        + "\n",
        encoding="utf-8",
    )
    written.append(md)
    return written
