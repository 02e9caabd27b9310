"""bracing-optimize's recorded file, DIR/tables.json (bracing_experiments.recorded): its report's tables (the
optimum's parameters beside the file's, the runs beside each other) and a ``search`` table (the trials by status,
the sampler and its seed, the best trial, this invocation's time), with the date, commit and machine, so that a
results page renders the optimiser's answer from the run (tools/docs_reference.py) instead of typing it."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_experiments.executors import Executor
from bracing_experiments.experiment import STATUS_OK
from bracing_experiments.optimize_specs import STATUS_FAILED, STATUS_INFEASIBLE, STATUS_INTERRUPTED, Problem
from bracing_experiments.recorded import TABLES_FILE, report_conclusions, report_tables, write_recorded

if TYPE_CHECKING:
    import optuna

    from bracing_experiments.optimize_search import SearchResult

SEARCH_TABLE = "search"
"""The key of the one-row table of the search's facts (column -> cell, as ``search`` is given)."""


def record_optimisation(report: Path, config: Path, search: dict[str, Any]) -> Path:
    """``report``'s tables and bold-lead paragraphs with the ``search`` table (one row: ``search``'s values under
    its keys) as a recorded file beside the report."""
    text = report.read_text()
    tables = {SEARCH_TABLE: {"header": list(search), "rows": [[str(value) for value in search.values()]]}}
    content = {"study": "optimize", "config": config.name, "tables": {**tables, **report_tables(text)}}
    content["conclusions"] = report_conclusions(text)
    return write_recorded(report.parent / TABLES_FILE, content)


def search_facts(
    problem: Problem,
    study: optuna.Study,
    best: optuna.trial.FrozenTrial | None,
    seed: int | None,
    result: SearchResult,
    executor: Executor,
) -> dict[str, Any]:
    """The search in one row of the recorded file: trials by status, the sampler, its seed, the best trial, and
    this invocation's trials, wall time [s] and executor."""
    statuses = [t.user_attrs.get("status", STATUS_INTERRUPTED) for t in study.get_trials(deepcopy=False)]
    return {
        "trials": len(statuses),
        "feasible": statuses.count(STATUS_OK),
        STATUS_INFEASIBLE: statuses.count(STATUS_INFEASIBLE),
        STATUS_FAILED: statuses.count(STATUS_FAILED),
        "sampler": f"{'NSGA-II' if len(problem.objectives) > 1 else 'TPE'} (Optuna), seed {seed}",
        "best trial": "none feasible" if best is None else best.number,
        "this invocation": f"{result.ran} trials in {result.wall_time_s:.1f} s on {executor.description}",
    }
