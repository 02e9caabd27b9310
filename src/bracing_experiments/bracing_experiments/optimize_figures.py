"""bracing-optimize's figures: each objective's convergence over the trials, and with two objectives the
Pareto front with the reference runs."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_core.numbers import number
from bracing_experiments.experiment import STATUS_OK
from bracing_experiments.optimize_specs import STATUS_INFEASIBLE, Problem

if TYPE_CHECKING:
    import optuna


def draw_convergence(problem: Problem, trials: Sequence[optuna.trial.FrozenTrial], output: Path) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(5.5 * len(problem.objectives), 3.8), layout="constrained")
    fig.suptitle(f"{problem.config.stem}: convergence")
    axes = fig.subplots(1, len(problem.objectives), squeeze=False)[0]
    for k, (ax, metric) in enumerate(zip(axes, problem.objectives, strict=True)):
        for status, colour, marker in ((STATUS_OK, "tab:blue", "o"), (STATUS_INFEASIBLE, "grey", "x")):
            points = [(t.number, t.values[k]) for t in trials if t.user_attrs.get("status") == status]
            if points:
                xs, ys = [p[0] for p in points], [p[1] for p in points]
                ax.scatter(xs, ys, s=14, color=colour, marker=marker, label=status)
        best, steps = math.inf, []
        for t in trials:
            if t.user_attrs.get("status") == STATUS_OK:
                best = min(best, t.values[k])
            if math.isfinite(best):
                steps.append((t.number, best))
        if steps:
            ax.step(*zip(*steps, strict=True), where="post", color="tab:red", label="best feasible so far")
        ax.set(xlabel="trial", ylabel=metric, yscale="log" if all(p[1] > 0 for p in steps) and steps else "linear")
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=7)
    fig.savefig(output / "convergence.png", dpi=110)


def draw_pareto(
    problem: Problem,
    study: optuna.Study,
    front: Sequence[optuna.trial.FrozenTrial],
    references: dict[str, dict[str, Any]],
    output: Path,
) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    x_metric, y_metric = problem.objectives
    fig = Figure(figsize=(6.5, 4.5), layout="constrained")
    ax = fig.subplots()
    for status, colour in ((STATUS_OK, "tab:blue"), (STATUS_INFEASIBLE, "lightgrey")):
        points = [t.values for t in study.get_trials(deepcopy=False) if t.user_attrs.get("status") == status]
        if points:
            ax.scatter([v[0] for v in points], [v[1] for v in points], s=12, color=colour, label=f"{status} trials")
    if front:
        ax.plot([t.values[0] for t in front], [t.values[1] for t in front], "o-", color="tab:red", label="Pareto front")
    for (name, row), marker in zip(references.items(), ("*", "s", "D"), strict=False):
        if number(row.get(x_metric)) and number(row.get(y_metric)):
            ax.scatter([row[x_metric]], [row[y_metric]], marker=marker, s=90, color="black", zorder=5)
            ax.annotate(name, (row[x_metric], row[y_metric]), textcoords="offset points", xytext=(6, 4), fontsize=8)
    ax.set(xlabel=x_metric, ylabel=y_metric, title=f"{problem.config.stem}: {x_metric} against {y_metric}")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.4)
    ax.legend(fontsize=7)
    fig.savefig(output / "pareto.png", dpi=110)
