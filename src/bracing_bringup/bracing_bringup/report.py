"""``bracing-report DIR/bag [--output DIR]``: the paper's figures, an animation and summary.json.

Writes into the output directory (default: the bag's parent directory):
``hand_y.png``, ``hand_z.png`` (the paper's Figs. 6/7, 9/10, 13/14), ``brace_x.png``, ``brace_y.png``
(Figs. 11/15), ``brace_z.png``, ``normal_force.png`` (Figs. 12/16), ``energy.png`` (Fig. 8),
``motor_temperature.png`` (each motor's winding temperature; runs with the thermal model only),
``summary.json`` and ``animation.gif`` / ``animation.mp4`` (the arm moving, see ``animation``).
Each title names the scenario (the bag's note of it, else the robot's name) and cites the paper's
figures only for the paper's scenario; a dotted vertical line marks each parameter the controller
was given while it ran (``ros2 param set``), with the new value.
A brace plot is drawn for each axis along which a braced contact's brace point moves
(``drawing.brace_axes``: the paper's elbow gets ``brace_y.png`` only); runs without contacts
skip the force plot; a bag without ``robot_description`` (recorded by an older version) gets
no animation unless ``--urdf`` names the robot.

``bracing-report BAG1 BAG2 ... --compare [--baseline NAME] [--output DIR]`` draws the runs side
by side instead (``compare_*.png`` and ``compare.md``, see ``compare``: ratios to the run NAME,
default the first; default output: the directory that holds the runs). Several bags without
``--compare``: a report for each. Exit code 2 on a missing or unreadable bag, or a baseline that
is none of the runs.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from bracing_bringup.animation import DEFAULT_INTERVAL_S, AnimationError, write_animation
from bracing_bringup.drawing import NO_ANIMATION, SUMMARY_FILE, report_series
from bracing_bringup.scene import DescriptionError
from bracing_bringup.summary import (
    BagReadError,
    BagSeries,
    format_summary,
    read_series,
    resolve_bag,
)

ANIMATION_FILES = ("animation.gif", "animation.mp4")
PAPER_SCENARIO = "paper_4link"
"""The scenario whose figures the paper has (config/paper_4link.yaml): only its titles cite them."""


def figure(title: str, ylabel: str) -> tuple[Figure, Axes]:
    """A report figure: one axes over time, titled and labelled."""
    fig = Figure(figsize=(7.0, 4.2), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(title)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.4)
    return fig, ax


def scenario_name(series: BagSeries) -> str:
    """The run's scenario: as the bag notes it, else its robot's name (URDF), else unknown."""
    if series.scenario:
        return series.scenario
    robot = re.search(r"<robot\b[^>]*\bname\s*=\s*[\"']([^\"']+)", series.robot_description or "")
    return f"robot {robot.group(1)}" if robot else "unknown scenario"


def title(series: BagSeries, what: str, paper: str = "") -> str:
    """``<scenario>: <what>``, citing the paper's figures ``paper`` (``Figs. 6, 9``) for its scenario only."""
    cited = f" (paper {paper})" if paper and series.scenario == PAPER_SCENARIO else ""
    return f"{scenario_name(series)}: {what}{cited}"


def mark_parameter_changes(ax: Axes, series: BagSeries) -> None:
    """A dotted vertical line at each parameter change of the run, with what was set."""
    for k, change in enumerate(series.parameter_changes):
        ax.axvline(change.t, color="0.3", ls=":", lw=1.2, label="parameter set" if k == 0 else None)
        ax.annotate(
            change.text(),
            xy=(change.t, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(3, -3),
            textcoords="offset points",
            rotation=90,
            va="top",
            ha="left",
            fontsize=7,
            color="0.3",
        )


def _plot_hand(series: BagSeries, axis: int, name: str) -> tuple[Figure, Axes]:
    figures = "Figs. 6, 9, 13" if axis == 1 else "Figs. 7, 10, 14"
    fig, ax = figure(title(series, f"hand {name} position", figures), f"hand {name} [m]")
    ax.plot(series.t, series.hand_desired[:, axis], "--", color="tab:red", label=f"target {name}_dh")
    ax.plot(series.t, series.hand_actual[:, axis], color="tab:blue", label=f"hand {name}_h")
    return fig, ax


def _plot_brace(series: BagSeries, axis: int, name: str) -> tuple[Figure, Axes]:
    figures = "Figs. 11, 15" if name == "y" else ""
    fig, ax = figure(title(series, f"brace point {name} position", figures), f"brace point {name} [m]")
    for cs in series.contacts.values():
        if cs.t_ctrl.size:  # braced (an obstacle has no brace point to follow)
            ax.plot(cs.t_ctrl, cs.brace_desired[:, axis], "--", label=f"{cs.name} target {name}")
            ax.plot(cs.t_ctrl, cs.brace_actual[:, axis], label=f"{cs.name} {name}")
    return fig, ax


def _plot_force(series: BagSeries) -> tuple[Figure, Axes]:
    fig, ax = figure(title(series, "contact (normal) forces", "Figs. 12, 16"), "normal force f_n [N]")
    for cs in series.contacts.values():
        if cs.t_ctrl.size:
            ax.plot(cs.t_ctrl, cs.normal_force_desired, "--", label=f"{cs.name} desired f_nd")
        if cs.t.size:
            ax.plot(cs.t, cs.normal_force, label=f"{cs.name} f_n")
    return fig, ax


def _plot_energy(series: BagSeries) -> tuple[Figure, Axes]:
    if series.input_mode == "torque":  # direct drive: the joints' mechanical work, no circuit
        fig, ax = figure(title(series, "mechanical energy of the joint drives (torque input)"), "energy [J]")
        ax.plot(series.motor_t, series.energy_consumed, label="consumed  ∫ Σ|τ dq| dt")
        ax.plot([], [], " ", label="copper loss: n/a (torque input: no motor circuit)")
    else:
        fig, ax = figure(title(series, "electrical energy of the motors", "Fig. 8"), "energy [J]")
        ax.plot(series.motor_t, series.energy_consumed, label="consumed  ∫ Σ|v i| dt")
        ax.plot(series.motor_t, series.copper_loss, label="copper loss  ∫ Σ R(T) i² dt")
    return fig, ax


def _plot_temperature(series: BagSeries) -> tuple[Figure, Axes]:
    fig, ax = figure(title(series, "motor winding temperatures (thermal model)"), "winding temperature T [°C]")
    for name, values in zip(series.motor_names, series.motor_temperature.T, strict=True):
        ax.plot(series.motor_t, values, label=name)
    return fig, ax


PLOTS: dict[str, Callable[[BagSeries], tuple[Figure, Axes]]] = {
    "hand_y": lambda series: _plot_hand(series, 1, "y"),
    "hand_z": lambda series: _plot_hand(series, 2, "z"),
    "brace_x": lambda series: _plot_brace(series, 0, "x"),
    "brace_y": lambda series: _plot_brace(series, 1, "y"),
    "brace_z": lambda series: _plot_brace(series, 2, "z"),
    "normal_force": _plot_force,
    "energy": _plot_energy,
    "motor_temperature": _plot_temperature,
}
"""Each plot by name, its file ``<name>.png`` (``drawing.file_names`` says which a run gets)."""


def plot_figure(name: str, series: BagSeries) -> Figure:
    """The report's plot ``name`` of ``series``, its parameter changes marked, legend drawn."""
    fig, ax = PLOTS[name](series)
    mark_parameter_changes(ax, series)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best")
    return fig


def _previous(path: Path) -> dict[str, Any]:
    """An existing summary.json (the report cannot know from the bag what the run measured besides)."""
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def _previous_wall_time(previous: dict[str, Any]) -> float | None:
    value = previous.get("wall_time_s")
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _previous_warnings(previous: dict[str, Any]) -> list[str]:
    value = previous.get("warnings")
    return [str(w) for w in value] if isinstance(value, list) else []


def default_output_dir(bag: str | Path) -> Path:
    """The bag's parent directory (the run directory DIR of DIR/bag)."""
    return resolve_bag(Path(bag)).resolve().parent


def write_report(
    bag: str | Path,
    output_dir: str | Path | None = None,
    wall_time_s: float | None = None,
    animation_interval_s: float | None = DEFAULT_INTERVAL_S,
    urdf: str | None = None,
) -> dict[str, Any]:
    """Read `bag`, write the plots, the animation and summary.json, and return the summary.

    The output directory defaults to the bag's parent. Without `wall_time_s`, the one in
    an existing summary.json there is kept, and so are its warnings (those the bag cannot show
    again: a target out of reach, slow real-time stepping). `animation_interval_s` is the sim time
    between animation frames (None: no animation); `urdf` (the text) animates a bag that lacks
    robot_description. Raises BagReadError on an unreadable bag.
    """
    series = read_series(bag)
    out = Path(output_dir) if output_dir is not None else default_output_dir(bag)
    previous = _previous(out / SUMMARY_FILE)
    if wall_time_s is None:
        wall_time_s = _previous_wall_time(previous)
    warnings = _previous_warnings(previous)
    return report_series(series, out, wall_time_s, animation_interval_s, urdf, warnings=warnings)


def draw_file(name: str, series: BagSeries, out: Path, animation_interval_s: float | None, urdf: str | None) -> str:
    """Draw the report's file ``name`` (``drawing.file_names``); what it wrote, or why it wrote nothing."""
    if name == "animation":
        assert animation_interval_s is not None
        return _animate(series, out, animation_interval_s, urdf)
    path = out / f"{name}.png"
    plot_figure(name, series).savefig(path, dpi=120)
    return f"plot {path.name}"


def _animate(series: BagSeries, out: Path, interval_s: float, urdf: str | None) -> str:
    try:
        write_animation(series, out, interval_s, urdf=urdf)
    except (AnimationError, DescriptionError) as exc:
        return f"{NO_ANIMATION}: {exc}"  # said by the process that reports (the drawing may be elsewhere)
    return "animation"


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    parser = argparse.ArgumentParser(
        prog="bracing-report",
        description="Plot a recorded bracing run (paper Figs. 6-16), animate the arm and write summary.json; "
        "with --compare, draw several runs side by side.",
    )
    parser.add_argument("bags", nargs="+", metavar="bag", help="rosbag2 bag directory (DIR/bag), or several")
    parser.add_argument("--compare", action="store_true", help="draw the runs side by side (compare_*.png, compare.md)")
    parser.add_argument(
        "--baseline",
        default=None,
        metavar="NAME",
        help="with --compare: the run (its directory name) the others are divided by (default: the first run)",
    )
    parser.add_argument(
        "--output",
        default=None,
        help="output directory (default: the bag's parent directory; with --compare, the directory holding the runs)",
    )
    parser.add_argument(
        "--wall-time", type=float, default=None, help="wall-clock duration of the run [s] (for real_time_factor)"
    )
    parser.add_argument(
        "--frame-interval",
        type=float,
        default=DEFAULT_INTERVAL_S,
        help=f"sim time between animation frames [s] (default {DEFAULT_INTERVAL_S})",
    )
    parser.add_argument("--no-animation", action="store_true", help="skip the animation")
    parser.add_argument("--urdf", type=Path, default=None, help="URDF to animate a bag without robot_description")
    args = parser.parse_args(None if argv is None else list(argv))
    if args.frame_interval <= 0:
        parser.error("--frame-interval must be > 0")
    if len(args.bags) > 1 and not args.compare and (args.output is not None or args.wall_time is not None):
        parser.error("--output and --wall-time name one run: give one bag, or add --compare")
    if args.baseline is not None and not args.compare:
        parser.error("--baseline is for --compare")
    try:
        if args.compare:
            from bracing_bringup.compare import BaselineError, default_compare_dir, write_comparison

            out = Path(args.output) if args.output is not None else default_compare_dir(args.bags)
            try:
                written = write_comparison(args.bags, out, baseline=args.baseline)
            except BaselineError as exc:
                print(f"bracing-report: error: {exc}", file=sys.stderr)
                return 2
            for path in written:
                print(f"written {path}")
            print((out / "compare.md").read_text(encoding="utf-8"))
            return 0
        urdf = args.urdf.read_text(encoding="utf-8") if args.urdf is not None else None
        for bag in args.bags:
            summary = write_report(
                bag,
                args.output,
                wall_time_s=args.wall_time,
                animation_interval_s=None if args.no_animation else args.frame_interval,
                urdf=urdf,
            )
            out = Path(args.output) if args.output is not None else default_output_dir(bag)
            print(format_summary(summary))
            print(f"report written to {out}")
    except (BagReadError, OSError) as exc:
        print(f"bracing-report: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
