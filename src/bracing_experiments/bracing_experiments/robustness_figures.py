"""bracing-study robustness's figures: per factor, the hand error, the braced force error and bracing's
energy ratios against the factor's levels, each law and run."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from bracing_analysis.summary import HAND_ERROR_T_MIN_S
from bracing_core.numbers import number
from bracing_core.variants import BRACED, FREE_SPACE, PASSIVE
from bracing_experiments.reporting import is_ok, ok_ratio
from bracing_experiments.robustness_specs import (
    ENERGY,
    FEEDBACK_LAW,
    HAND_RMS,
    LAW_TEXT,
    LAWS,
    NOMINAL_LEVEL,
    PAPER_LAW,
    TORQUE,
    VARIANTS,
    Factor,
    Level,
    Robustness,
    force_error,
)
from bracing_experiments.running import ResultsStore

if TYPE_CHECKING:
    from matplotlib.axes import Axes


_LAW_COLOURS = {PAPER_LAW: "tab:blue", FEEDBACK_LAW: "tab:orange"}
_VARIANT_STYLES = {BRACED.name: "-", PASSIVE.name: ":", FREE_SPACE.name: "--"}
_Points = list[tuple[float, Factor | None, Level]]  # (x, factor or None for the nominal, level), by x


def _series(
    study: Robustness,
    rows: Mapping[str, dict[str, Any]],
    points: _Points,
    law: str,
    variant: str,
    get: Any,
    mode: str | None = None,
) -> list[float]:
    """``get`` of that run's row at each point; nan where it is not a number."""
    values = []
    for _, where, level in points:
        value = get(study.row(rows, where, level, law, variant, mode))
        values.append(float(value) if number(value) else math.nan)
    return values


def _plot_hand(ax: Axes, study: Robustness, rows: Mapping[str, dict[str, Any]], points: _Points, law: str) -> None:
    xs = [p[0] for p in points]
    for variant in VARIANTS:
        hand = _series(study, rows, points, law, variant.name, lambda r: r.get(HAND_RMS) if is_ok(r) else None)
        ax.plot(
            xs,
            hand,
            marker="o",
            ls=_VARIANT_STYLES[variant.name],
            color=_LAW_COLOURS[law],
            label=f"{variant.column}, {LAW_TEXT[law]}",
        )


def _plotforce_error(
    ax: Axes, study: Robustness, rows: Mapping[str, dict[str, Any]], points: _Points, law: str, factor: Factor
) -> bool:
    """The braced force error in the file's mode (and torque input's, when the study has those rows);
    True when a value is finite (a log axis can draw it)."""
    xs = [p[0] for p in points]
    force = _series(study, rows, points, law, BRACED.name, force_error)
    finite = bool(np.isfinite(force).any())
    ax.plot(
        xs, [max(v, 1e-15) for v in force], marker="o", color=_LAW_COLOURS[law], label=f"{study.mode}, {LAW_TEXT[law]}"
    )
    if study.torque_rows and factor.torque:
        torque = _series(study, rows, points, law, BRACED.name, force_error, TORQUE)
        finite = finite or bool(np.isfinite(torque).any())
        ax.plot(
            xs,
            [max(v, 1e-15) for v in torque],
            marker="s",
            ls="--",
            color=_LAW_COLOURS[law],
            alpha=0.7,
            label=f"torque, {'force feedback' if law == FEEDBACK_LAW else LAW_TEXT[law]}",
        )
    return finite


def _plot_energy_ratios(
    ax: Axes, study: Robustness, rows: Mapping[str, dict[str, Any]], points: _Points, law: str
) -> None:
    """Braced energy over free space's and over resting passively's."""
    xs = [p[0] for p in points]
    for baseline, marker in ((FREE_SPACE, "o"), (PASSIVE, "^")):
        values = []
        for _, where, level in points:
            braced = study.row(rows, where, level, law, BRACED.name)
            other = study.row(rows, where, level, law, baseline.name)
            value = ok_ratio(ENERGY, braced, other)
            values.append(value if value is not None else math.nan)
        ax.plot(
            xs,
            values,
            marker=marker,
            ls=_VARIANT_STYLES[baseline.name],
            color=_LAW_COLOURS[law],
            label=f"braced / {baseline.column}, {LAW_TEXT[law]}",
        )


def draw_factor(
    study: Robustness, store: ResultsStore, rows: Mapping[str, dict[str, Any]], factor: Factor, name: str
) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    points = sorted(
        [(factor.nominal, None, NOMINAL_LEVEL), *((lv.value, factor, lv) for lv in factor.levels)], key=lambda p: p[0]
    )
    fig = Figure(figsize=(14, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: {factor.title.lower()} ({study.mode} input unless marked)")
    hand_ax, force_ax, ratio_ax = fig.subplots(1, 3)
    logarithmic = False
    for law in LAWS:
        _plot_hand(hand_ax, study, rows, points, law)
        finite = _plotforce_error(force_ax, study, rows, points, law, factor)
        logarithmic = logarithmic or finite
        _plot_energy_ratios(ratio_ax, study, rows, points, law)
    ratio_ax.axhline(1.0, color="grey", lw=1.0)
    for ax in (hand_ax, force_ax, ratio_ax):
        ax.axvline(factor.nominal, color="grey", ls=":", lw=0.8)
        ax.set_xlabel(factor.axis)
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=6)
    hand_ax.set(title=f"hand RMS error (t >= {HAND_ERROR_T_MIN_S:g} s)", ylabel="[m]")
    force_ax.set(title=f"braced |f_n - f_nd| RMS (t >= {HAND_ERROR_T_MIN_S:g} s if run so long)", ylabel="[N]")
    if logarithmic:  # (a log axis without a finite value refuses to draw)
        force_ax.set_yscale("log")  # torque input's is ~1e-14 N where the model is exact
    ratio_ax.set(title="energy ratio of bracing (< 1: bracing saves)", ylabel="ratio")
    fig.savefig(store.output / name, dpi=110)
