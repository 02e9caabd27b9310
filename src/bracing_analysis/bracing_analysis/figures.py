"""The report's figures, one file each (``draw_file``): the paper's plots of a recorded run and
its animation, drawn with matplotlib (Agg). The processes that draw them (``drawing``) import
this module once; ``compare`` draws its side-by-side figures with the same ``figure``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from bracing_analysis.animation import AnimationError, write_animation
from bracing_analysis.axes import contact_brace_axes
from bracing_analysis.series import BagSeries, scenario_name, touched_kept_out
from bracing_core.contact_roles import BRACED, by_role
from bracing_core.kinematics import DescriptionError

NO_ANIMATION = "no animation"
"""How ``draw_file`` says that a bag cannot be animated (the reason follows)."""

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


_HAND_FIGURES = {"y": "Figs. 6, 9, 13", "z": "Figs. 7, 10, 14"}
"""The paper's figures of the hand along each axis it has (its arm moves in the y-z plane)."""


def mark_targets(ax: Axes, series: BagSeries, task: str, axis: int, label: str) -> None:
    """Each target the controller accepted for ``task`` while the run went (``series.targets``: never a
    refused one): a marker where and when it was taken (a point), or the path's poses at their stamps
    joined to when it was taken (a path). A run without any draws nothing."""
    for k, sent in enumerate(s for s in series.targets if s.task == task):
        first = label if k == 0 else None
        if len(sent.points) == 1 and sent.times[0] == sent.t:
            ax.plot([sent.t], sent.points[:, axis], "x", color="black", ms=8, mew=2, label=first)
        else:
            ax.plot(sent.times, sent.points[:, axis], "x:", color="black", ms=6, mew=1.5, label=first)
            ax.axvline(sent.t, color="black", ls=":", lw=0.8)


def _plot_hand(series: BagSeries, axis: int, name: str) -> tuple[Figure, Axes]:
    fig, ax = figure(title(series, f"hand {name} position", _HAND_FIGURES.get(name, "")), f"hand {name} [m]")
    ax.plot(series.t, series.hand_desired[:, axis], "--", color="tab:red", label=f"target {name}_dh")
    ax.plot(series.t, series.hand_actual[:, axis], color="tab:blue", label=f"hand {name}_h")
    # with sensors: what the controller believed, beside the truth
    if series.hand_measured.size and series.hand_measured.shape[0] == series.t.size:
        ax.plot(series.t, series.hand_measured[:, axis], ":", color="tab:green", label=f"as measured {name}_h")
    mark_targets(ax, series, "hand", axis, "hand_target / hand_path accepted")
    return fig, ax


def _plot_brace(series: BagSeries, axis: int, name: str) -> tuple[Figure, Axes]:
    """Each braced contact drawn along ``name`` (``drawing.contact_brace_axes``: its task's axes)."""
    figures = "Figs. 11, 15" if name == "y" else ""
    fig, ax = figure(title(series, f"brace point {name} position", figures), f"brace point {name} [m]")
    for cs in series.contacts.values():
        if cs.t_ctrl.size and name in contact_brace_axes(series, cs):  # braced (an obstacle has no brace point)
            ax.plot(cs.t_ctrl, cs.brace_desired[:, axis], "--", label=f"{cs.name} target {name}")
            ax.plot(cs.t_ctrl, cs.brace_actual[:, axis], label=f"{cs.name} {name}")
            if cs.brace_measured.size and cs.brace_measured.shape[0] == cs.t_ctrl.size:  # with sensors: its view
                ax.plot(cs.t_ctrl, cs.brace_measured[:, axis], ":", label=f"{cs.name} {name} as measured")
            mark_targets(ax, series, cs.name, axis, f"brace_target/{cs.name} accepted")
    return fig, ax


def _plot_force(series: BagSeries) -> tuple[Figure, Axes]:
    """The scenario's contacts (role braced: braced points and obstacles); the kept-out frames and links
    have their own figure (``_plot_kept_out_force``)."""
    fig, ax = figure(title(series, "contact (normal) forces", "Figs. 12, 16"), "normal force f_n [N]")
    for cs in by_role(series.contacts, BRACED).values():
        if cs.t_ctrl.size:
            ax.plot(cs.t_ctrl, cs.normal_force_desired, "--", label=f"{cs.name} desired f_nd")
        if cs.t.size:
            ax.plot(cs.t, cs.normal_force, label=f"{cs.name} f_n")
    return fig, ax


def _plot_kept_out_force(series: BagSeries) -> tuple[Figure, Axes]:
    """The force on each frame or link kept out of a surface (``<frame or link>@<contact>``) that touched."""
    fig, ax = figure(title(series, "kept-out frames and links touching a surface"), "normal force f_n [N]")
    for cs in touched_kept_out(series):
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


def _plot_orientation(series: BagSeries) -> tuple[Figure, Axes]:
    """The hand frame's orientation error log(R_d R^T) per world axis and its angle (hand_orientation_error)."""
    fig, ax = figure(title(series, "hand orientation error"), "orientation error [rad]")
    turn = series.hand_orientation_error
    for axis, name in enumerate("xyz"):
        ax.plot(series.t, turn[:, axis], label=f"about {name}", linewidth=0.8)
    ax.plot(series.t, np.linalg.norm(turn, axis=1), color="black", label="angle |log(R_d R^T)|")
    return fig, ax


PLOTS: dict[str, Callable[[BagSeries], tuple[Figure, Axes]]] = {
    "hand_x": lambda series: _plot_hand(series, 0, "x"),
    "hand_y": lambda series: _plot_hand(series, 1, "y"),
    "hand_z": lambda series: _plot_hand(series, 2, "z"),
    "brace_x": lambda series: _plot_brace(series, 0, "x"),
    "brace_y": lambda series: _plot_brace(series, 1, "y"),
    "brace_z": lambda series: _plot_brace(series, 2, "z"),
    "normal_force": _plot_force,
    "kept_out_force": _plot_kept_out_force,
    "energy": _plot_energy,
    "motor_temperature": _plot_temperature,
    "hand_orientation": _plot_orientation,
}
"""Each plot by name, its file ``<name>.png`` (``drawing.file_names`` says which a run gets)."""


def plot_figure(name: str, series: BagSeries) -> Figure:
    """The report's plot ``name`` of ``series``, its parameter changes marked, legend drawn."""
    fig, ax = PLOTS[name](series)
    mark_parameter_changes(ax, series)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best")
    return fig


def draw_file(
    name: str, series: BagSeries, out: Path, animation_interval_s: float | None, urdf: str | None
) -> tuple[str, bool]:
    """Draw the report's file ``name`` (``drawing.file_names``): what it wrote, or why it wrote
    nothing (said by the process that reports: the drawing may be in another), and whether it wrote."""
    if name == "animation":
        assert animation_interval_s is not None
        try:
            write_animation(series, out, animation_interval_s, urdf=urdf)
        except (AnimationError, DescriptionError) as exc:
            return f"{NO_ANIMATION}: {exc}", False
        return "animation", True
    path = out / f"{name}.png"
    plot_figure(name, series).savefig(path, dpi=120)
    return f"plot {path.name}", True
