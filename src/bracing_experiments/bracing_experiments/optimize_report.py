"""What bracing-optimize's study found: the trials' table, the optimum as a scenario file (best.yaml) and
DIR/report.md (its figures: optimize_figures)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_core import rcl_yaml
from bracing_core.numbers import cell, markdown_table
from bracing_core.overrides import CONTROLLER, SIMULATOR, destination, node_params
from bracing_experiments.experiment import STATUS_OK
from bracing_experiments.optimize_figures import draw_convergence, draw_pareto
from bracing_experiments.optimize_specs import STATUS_FAILED, STATUS_INFEASIBLE, STATUS_INTERRUPTED, Problem
from bracing_experiments.running import write_tables as write_sweep_tables

if TYPE_CHECKING:
    import optuna

TRIALS_PARQUET, TRIALS_CSV, BEST_YAML, REPORT = "trials.parquet", "trials.csv", "best.yaml", "report.md"


def trial_rows(study: optuna.Study, problem: Problem) -> list[dict[str, Any]]:
    """One row per trial: number, status, the varied values, objectives, constraint margins, the run's metrics."""
    rows = []
    for trial in study.get_trials(deepcopy=False):
        attrs = trial.user_attrs
        row: dict[str, Any] = {"trial": trial.number, "status": attrs.get("status", STATUS_INTERRUPTED)}
        row["error"] = attrs.get("error")
        row.update({v.name: trial.params.get(v.name) for v in problem.varies})
        run = dict(attrs.get("row", {}))
        run.pop("status", None)
        run.pop("error", None)
        run.pop("trial", None)
        row.update({key: value for key, value in run.items() if key not in row})
        rows.append(row)
    return rows


def feasible(study: optuna.Study) -> list[optuna.trial.FrozenTrial]:
    """Trials whose run was ok, met the constraints and were told their values."""
    trials = study.get_trials(deepcopy=False)
    return [t for t in trials if t.user_attrs.get("status") == STATUS_OK and t.values is not None]


def pareto_front(trials: Sequence[optuna.trial.FrozenTrial]) -> list[optuna.trial.FrozenTrial]:
    """The trials no other trial dominates (every objective <=, one <), by the first objective."""
    front = [
        t
        for t in trials
        if not any(
            all(a <= b for a, b in zip(o.values, t.values, strict=True)) and o.values != t.values for o in trials
        )
    ]
    return sorted(front, key=lambda t: t.values[0])


def best_trial(study: optuna.Study) -> optuna.trial.FrozenTrial | None:
    """The feasible trial of least first objective (with several objectives: on the Pareto front, the
    least first objective; the front itself is in the report)."""
    candidates = feasible(study)
    return min(candidates, key=lambda t: (t.values[0], t.number)) if candidates else None


def write_best(problem: Problem, trial: optuna.trial.FrozenTrial, path: Path) -> None:
    """A complete scenario file with the trial's values: both nodes' parameters as the trial ran them
    (its duration too), the shared ones under /**, every string quoted (rcl_yaml.dump)."""
    spec = problem.spec(dict(trial.params))
    sim = dict(spec.sim_params, duration=spec.duration)
    ctl = dict(spec.ctl_params)
    shared = {k: v for k, v in sim.items() if k in ctl and ctl[k] == v}  # what the file's /** section holds
    document = {
        "/**": {"ros__parameters": shared},
        SIMULATOR: {"ros__parameters": {k: v for k, v in sim.items() if k not in shared}},
        CONTROLLER: {"ros__parameters": {k: v for k, v in ctl.items() if k not in shared}},
    }
    values = ", ".join(f"{name} = {value!r}" for name, value in trial.params.items())
    objectives = ", ".join(f"{m} = {v:.6g}" for m, v in zip(problem.objectives, trial.values, strict=True))
    header = [
        f"# bracing-optimize: trial {trial.number} of {problem.config} ({values}): {objectives}.",
        "# Every parameter both nodes ran the trial with. Run it: bracing-pair --config <this file>",
    ]
    path.write_text("\n".join(header) + "\n" + rcl_yaml.dump(document))


def write_outputs(
    problem: Problem, study: optuna.Study, output: Path, references: dict[str, dict[str, Any]], note: str = ""
) -> optuna.trial.FrozenTrial | None:
    """trials.csv / .parquet, best.yaml (when a trial is feasible), report.md with its figures."""
    rows = trial_rows(study, problem)
    write_sweep_tables(output, rows, ["trial", *(v.name for v in problem.varies)], TRIALS_PARQUET, TRIALS_CSV)
    best = best_trial(study)
    if best is not None:
        write_best(problem, best, output / BEST_YAML)
    write_report(problem, study, output, best, references, note)
    return best


def scenario_cell(value: Any) -> str:
    """A value as the scenario file writes it (true, false) or a metric's cell."""
    return cell(value, bools=("true", "false"))


def changes(problem: Problem, trial: optuna.trial.FrozenTrial) -> list[tuple[str, Any, Any]]:
    """(parameter, the file's value, the optimum's) for every varied parameter."""
    out = []
    for vary in problem.varies:
        if vary.index is None:
            node = CONTROLLER if destination(vary.key) in ("shared", CONTROLLER) else SIMULATOR
            before = problem.base.get(vary.key, node_params(problem.config)[node].get(vary.key))
        else:
            before = problem.lists[vary.key][vary.index]
        out.append((vary.name, before, trial.params[vary.name]))
    return out


def write_report(
    problem: Problem,
    study: optuna.Study,
    output: Path,
    best: optuna.trial.FrozenTrial | None,
    references: dict[str, dict[str, Any]],
    note: str = "",
) -> Path:
    import matplotlib  # imported where used: matplotlib ~460 ms (python -X importtime)

    matplotlib.use("Agg")
    trials = study.get_trials(deepcopy=False)
    statuses = [t.user_attrs.get("status", STATUS_INTERRUPTED) for t in trials]
    count = {s: statuses.count(s) for s in (STATUS_OK, STATUS_INFEASIBLE, STATUS_FAILED, STATUS_INTERRUPTED)}
    command = " ".join(
        ["bracing-optimize", "--config", str(problem.config), *(v.flag for v in problem.varies)]
        + [f"--minimize {m}" for m in problem.objectives]
        + [f"--subject-to '{c.text}'" for c in problem.constraints]
        + ([f"--duration {problem.duration:g}"] if problem.duration else [])
    )
    metrics = list(dict.fromkeys([*problem.objectives, *(c.metric for c in problem.constraints)]))
    lines = [
        f"# Optimisation: {problem.config.name}",
        "",
        f"`{command}`",
        "",
        f"{len(trials)} trials: {count[STATUS_OK]} feasible, {count[STATUS_INFEASIBLE]} infeasible, "
        f"{count[STATUS_FAILED]} failed, {count[STATUS_INTERRUPTED]} interrupted. "
        f"Sampler: {'NSGA-II' if len(problem.objectives) > 1 else 'TPE'} (Optuna), constraints: "
        f"{', '.join(c.text for c in problem.constraints) or 'none'}. {note}",
        "",
    ]
    if best is None:
        lines += ["No feasible trial: no best.yaml.", ""]
    else:
        lines += [
            f"**Optimum** (trial {best.number}; `bracing-pair --config {BEST_YAML}` runs it):",
            "",
            markdown_table(
                ["parameter", "the file's", "optimum"],
                [[name, scenario_cell(before), scenario_cell(after)] for name, before, after in changes(problem, best)],
            ),
            "",
        ]
    runs = ([("optimum", best.user_attrs["row"])] if best is not None else []) + list(references.items())
    table = markdown_table(
        ["run", *metrics], [[name, *(scenario_cell(row.get(m)) for m in metrics)] for name, row in runs]
    )
    lines += [table, "", "![convergence](convergence.png)", ""]
    draw_convergence(problem, trials, output)
    if len(problem.objectives) == 2:
        front = pareto_front(feasible(study))
        lines += [
            f"**Pareto front** ({len(front)} feasible trials no other beats on both objectives):",
            "",
            "![Pareto front](pareto.png)",
            "",
        ]
        draw_pareto(problem, study, front, references, output)
    path = output / REPORT
    path.write_text("\n".join(lines))
    return path
