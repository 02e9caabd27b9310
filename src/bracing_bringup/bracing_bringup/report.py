"""``bracing-report DIR/bag [--output DIR]``: the paper's figures and summary.json.

Writes into the output directory (default: the bag's parent directory):
``hand_y.png``, ``hand_z.png`` (Figs. 6/7, 9/10, 13/14), ``brace_y.png`` (Figs. 11/15),
``normal_force.png`` (Figs. 12/16), ``energy.png`` (Fig. 8) and ``summary.json``.
Runs without contacts skip the brace and force plots. Exit code 2 on a missing or
unreadable bag.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from bracing_bringup.summary import (
    BagReadError,
    BagSeries,
    compute_summary,
    read_series,
    resolve_bag,
)

SUMMARY_FILE = "summary.json"


def _figure(title: str, ylabel: str) -> tuple[Figure, Axes]:
    fig = Figure(figsize=(7.0, 4.2), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(title)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.4)
    return fig, ax


def _save(fig: Figure, ax: Axes, path: Path) -> Path:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best")
    fig.savefig(path, dpi=120)
    return path


def _plot_hand(series: BagSeries, out: Path, axis: int, name: str) -> Path:
    fig, ax = _figure(
        f"Hand {name} position (paper Figs. {'6, 9, 13' if axis == 1 else '7, 10, 14'})", f"hand {name} [m]"
    )
    ax.plot(series.t, series.hand_desired[:, axis], "--", color="tab:red", label=f"target {name}_dh")
    ax.plot(series.t, series.hand_actual[:, axis], color="tab:blue", label=f"hand {name}_h")
    return _save(fig, ax, out / f"hand_{name}.png")


def _plot_brace(series: BagSeries, out: Path) -> Path:
    fig, ax = _figure("Brace point y position (paper Figs. 11, 15)", "brace point y [m]")
    for cs in series.contacts.values():
        if cs.t_ctrl.size:
            ax.plot(cs.t_ctrl, cs.brace_desired[:, 1], "--", label=f"{cs.name} target y")
            ax.plot(cs.t_ctrl, cs.brace_actual[:, 1], label=f"{cs.name} y")
        elif cs.t.size:
            ax.plot(cs.t, cs.position[:, 1], label=f"{cs.name} y (simulator)")
    return _save(fig, ax, out / "brace_y.png")


def _plot_force(series: BagSeries, out: Path) -> Path:
    fig, ax = _figure("Reaction (normal) force at the brace (paper Figs. 12, 16)", "normal force f_n [N]")
    for cs in series.contacts.values():
        if cs.t_ctrl.size:
            ax.plot(cs.t_ctrl, cs.normal_force_desired, "--", label=f"{cs.name} desired f_nd")
        if cs.t.size:
            ax.plot(cs.t, cs.normal_force, label=f"{cs.name} f_n")
    return _save(fig, ax, out / "normal_force.png")


def _plot_energy(series: BagSeries, out: Path) -> Path:
    fig, ax = _figure("Electrical energy of the motors (paper Fig. 8)", "energy [J]")
    ax.plot(series.motor_t, series.energy_consumed, label="consumed  ∫ Σ|v i| dt")
    ax.plot(series.motor_t, series.copper_loss, label="copper loss  ∫ Σ R i² dt")
    return _save(fig, ax, out / "energy.png")


def plot_series(series: BagSeries, output_dir: str | Path) -> list[Path]:
    """Write the PNG plots the data allows; returns the files written."""
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    if series.t.size:
        written.append(_plot_hand(series, out, 1, "y"))
        written.append(_plot_hand(series, out, 2, "z"))
    if any(cs.t_ctrl.size or cs.t.size for cs in series.contacts.values()):
        written.append(_plot_brace(series, out))
        written.append(_plot_force(series, out))
    if series.motor_t.size:
        written.append(_plot_energy(series, out))
    return written


def _previous_wall_time(path: Path) -> float | None:
    try:
        value = json.loads(path.read_text(encoding="utf-8")).get("wall_time_s")
    except (OSError, ValueError, AttributeError):
        return None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def default_output_dir(bag: str | Path) -> Path:
    """The bag's parent directory (the run directory DIR of DIR/bag)."""
    return resolve_bag(Path(bag)).resolve().parent


def write_report(
    bag: str | Path,
    output_dir: str | Path | None = None,
    wall_time_s: float | None = None,
) -> dict[str, Any]:
    """Read `bag`, write the plots and summary.json, and return the summary.

    The output directory defaults to the bag's parent. Without `wall_time_s`, the one in
    an existing summary.json there is kept. Raises BagReadError on an unreadable bag.
    """
    series = read_series(bag)
    out = Path(output_dir) if output_dir is not None else default_output_dir(bag)
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / SUMMARY_FILE
    if wall_time_s is None:
        wall_time_s = _previous_wall_time(summary_path)
    plot_series(series, out)
    summary = compute_summary(series, wall_time_s=wall_time_s)
    summary_path.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as an aligned two-column table."""
    width = max(len(k) for k in summary)
    lines = []
    for key, value in summary.items():
        text = "n/a" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<{width}}  {text}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    parser = argparse.ArgumentParser(
        prog="bracing-report",
        description="Plot a recorded bracing run (paper Figs. 6-16) and write summary.json.",
    )
    parser.add_argument("bag", help="rosbag2 bag directory (DIR/bag)")
    parser.add_argument("--output", default=None, help="output directory (default: the bag's parent directory)")
    parser.add_argument(
        "--wall-time", type=float, default=None, help="wall-clock duration of the run [s] (for real_time_factor)"
    )
    args = parser.parse_args(None if argv is None else list(argv))
    try:
        summary = write_report(args.bag, args.output, wall_time_s=args.wall_time)
    except BagReadError as exc:
        print(f"bracing-report: error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.output) if args.output is not None else default_output_dir(args.bag)
    print(format_summary(summary))
    print(f"report written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
