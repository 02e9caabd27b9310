"""bracing-study paper's figures: hand error and energy over time (braced, passive, free), the gains'
errors, and the placement grid with the optimiser's optimum."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from bracing_experiments.experiment import FORCE_MAX_ERROR_KEY
from bracing_experiments.reporting import braced_forces, is_ok, run_arrays
from bracing_experiments.running import ResultsStore
from bracing_experiments.study_specs import ENERGY, HAND_RMS, Study


def draw_bracing(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(11, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: braced, passive and free")
    error_ax, energy_ax = fig.subplots(1, 2)
    colours = {
        ("voltage", False): "tab:blue",
        ("voltage", True): "tab:cyan",
        ("torque", False): "tab:red",
        ("torque", True): "tab:orange",
    }
    runs = [(spec, "braced" if spec.varied["bracing"] else "free") for spec in study.bracing]
    runs += [(spec, "passive") for spec in study.passive]
    for spec, kind in runs:
        if not is_ok(rows.get(spec.run_id)):
            continue
        data = run_arrays(store, spec.run_id)
        if data is None:
            continue
        v = spec.varied
        gravity = "g comp." if v["gravity_compensation"] else "no g comp."
        label = f"{kind}, {v['input_mode']}, {gravity}"
        style = dict(
            color=colours[(v["input_mode"], v["gravity_compensation"])],
            ls={"braced": "-", "free": "--", "passive": ":"}[kind],
        )
        error = np.linalg.norm(data["hand_desired"] - data["hand_actual"], axis=1)
        error_ax.plot(data["time"], error, label=label, lw=1.2, **style)
        energy_ax.plot(data["time"], data["energy_consumed"], label=label, lw=1.2, **style)
    error_ax.set(title="hand error |r_hd - r_h|", xlabel="time [s]", ylabel="[m]", yscale="log")
    energy_ax.set(title="energy consumed (torque input: mechanical)", xlabel="time [s]", ylabel="[J]", yscale="log")
    for ax in (error_ax, energy_ax):
        ax.grid(True, alpha=0.4)
    energy_ax.legend(fontsize=6, loc="lower right", ncol=2)
    fig.savefig(store.output / "bracing.png", dpi=110)


def draw_gains(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(14, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: gains scaled together")
    force_ax, position_ax, series_ax = fig.subplots(1, 3)
    colours = {"torque": "tab:red", "voltage": "tab:blue"}
    for mode in ("torque", "voltage"):
        points = [
            (s.varied["gain_scale"], rows[s.run_id])
            for s in study.gains
            if s.varied["input_mode"] == mode and is_ok(rows.get(s.run_id))
        ]
        if not points:
            continue
        scales = [p[0] for p in points]
        force = [max(float(p[1].get(FORCE_MAX_ERROR_KEY) or 0.0), 1e-16) for p in points]
        force_ax.plot(scales, force, "o-", color=colours[mode], label=f"{mode}: max |f_n - f_nd|")
        for key, marker, name in (("hand_rms_error_m", "o-", "hand RMS"), ("brace_rms_error_m", "s--", "brace RMS")):
            position_ax.plot(
                scales, [p[1].get(key) for p in points], marker, color=colours[mode], label=f"{mode}: {name}"
            )
    for spec in study.gains:
        if spec.varied["input_mode"] != "voltage" or not is_ok(rows.get(spec.run_id)):
            continue
        data = run_arrays(store, spec.run_id)
        if data is not None and data["desired_normal_force"].size:
            series_ax.plot(
                data["time"], braced_forces(data)[:, 0], lw=1.0, label=f"voltage, x{spec.varied['gain_scale']:g}"
            )
            desired = float(data["desired_normal_force"][0])
    if series_ax.lines:
        series_ax.axhline(desired, color="tab:red", ls="--", lw=1.0, label="f_nd (torque input: every run)")
    force_ax.axhline(np.finfo(float).eps * 10, color="grey", ls=":", lw=1.0)
    force_ax.set(
        title="force error (torque input: machine precision)",
        xlabel="gain scale",
        ylabel="[N]",
        xscale="log",
        yscale="log",
    )
    position_ax.set(title="position errors", xlabel="gain scale", ylabel="[m]", xscale="log")
    series_ax.set(title="normal force, voltage input" + study.paper(" (Fig. 16)"), xlabel="time [s]", ylabel="f_n [N]")
    for ax in (force_ax, position_ax, series_ax):
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=7)
    fig.savefig(store.output / "gains.png", dpi=110)


_LEAST: dict[str, Any] = dict(
    marker="*", markersize=22, markerfacecolor="none", markeredgecolor="red", mew=2, ls="none"
)
"""The placement figure's mark of the grid's least cell (a hollow red star)."""
_OPTIMUM: dict[str, Any] = dict(marker="X", markersize=13, color="magenta", markeredgecolor="white", ls="none")
"""Its mark of the optimiser's optimum."""


def grid_position(value: float, ticks: Sequence[float]) -> float:
    """``value`` on an image axis whose ticks sit at 0, 1, ...: piecewise linear between them,
    extended past the ends by the end intervals (an optimum outside the grid lands outside it)."""
    if len(ticks) < 2:
        return 0.0
    k = int(np.clip(np.searchsorted(ticks, value) - 1, 0, len(ticks) - 2))
    return k + (value - ticks[k]) / (ticks[k + 1] - ticks[k])


def draw_placement(
    study: Study, store: ResultsStore, grids: dict[str, np.ndarray], optimum: tuple[float, float] | None
) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(11, 4.0), layout="constrained")
    fig.suptitle(f"{study.scenario}: brace placement and force")
    axes = fig.subplots(1, 2)
    for ax, (key, title) in zip(axes, ((ENERGY, "energy consumed [J]"), (HAND_RMS, "hand RMS error [m]")), strict=True):
        grid = grids[key]
        image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        fig.colorbar(image, ax=ax)
        ax.set_xticks(range(len(study.targets)), [f"{t:.3f}" for t in study.targets])
        ax.set_yticks(range(len(study.forces)), [f"{f:g}" for f in study.forces])
        ax.set(title=title, xlabel=f"brace target {study.axis} [m]", ylabel="desired normal force [N]")
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                text = f"{grid[i, j]:.3g}" if np.isfinite(grid[i, j]) else "failed"
                ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white")
        if np.isfinite(grid).any():
            i, j = (int(x) for x in np.unravel_index(np.nanargmin(grid), grid.shape))
            ax.plot(j, i, label="grid's least", **_LEAST)
        if optimum is not None:
            x, y = grid_position(optimum[0], study.targets), grid_position(optimum[1], study.forces)
            ax.plot(x, y, label=f"optimum ({study.axis} {optimum[0]:.3f} m, {optimum[1]:.3g} N)", **_OPTIMUM)
            ax.set_xlim(min(-0.5, x - 0.4), max(len(study.targets) - 0.5, x + 0.4))
            ax.set_ylim(min(-0.5, y - 0.4), max(len(study.forces) - 0.5, y + 0.4))
        ax.legend(fontsize=7, loc="lower left", framealpha=0.8, markerscale=0.6)
    fig.savefig(store.output / "placement.png", dpi=110)
