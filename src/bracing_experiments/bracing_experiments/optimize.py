"""bracing-optimize: the scenario parameters that minimise a metric, found by Optuna on the sweeps' executors.

    bracing-optimize --config F --vary KEY=LOW:HIGH [--vary ...] --minimize METRIC [--minimize METRIC]
                     [--subject-to 'METRIC<=V' ...] [--trials N] [--workers N | --scheduler ADDRESS]
                     [--duration S] --output DIR

KEY is a numeric scenario parameter as ``--set`` spells it, ``KEY[i]`` an element of a list
(``contacts.elbow.target[1]``: the brace target's y; an empty target list is the contact's start
position, as a run reads it). METRIC is a column of a sweep's table (a summary.json key, dotted for a
contact's: ``contacts.elbow.slip_m``). One objective: Optuna's TPE sampler; two or more: NSGA-II; both
with the constraints (``METRIC<=V`` or ``METRIC>=V``) as each trial's constraint values
(``Trial.set_constraint``, which both samplers read). Each trial is one
in-process run (``bracing_experiments.experiment.execute_run``) built by the sweeps' ``make_spec``, on
local worker processes or a Dask cluster, ``workers`` trials at a time.

DIR/study.db is the Optuna study (SQLite): the same command again resumes it up to N trials; Ctrl-C
keeps every finished trial. A failing run is a failed trial (its error in the table), a run off the
constraints an infeasible one; neither stops the search. Writes DIR/trials.csv and .parquet (every
trial), DIR/best.yaml (the scenario file with the optimum filled in: ``bracing-pair --config
DIR/best.yaml`` runs it as is), DIR/report.md with convergence.png (and pareto.png with two objectives).
Exit 0 when every trial ran, 1 when one failed, 2 on a configuration error before any trial, 130 when
interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from bracing_experiments.cli import (
    EXIT_FAILED,
    add_duration,
    add_executor,
    add_output,
    add_overrides,
    add_progress,
    check_options,
    run_command,
)
from bracing_experiments.executors import Executor
from bracing_experiments.optimize_report import BEST_YAML, REPORT, TRIALS_CSV, scenario_cell
from bracing_experiments.optimize_search import STUDY_DB, Optimum, check_manifest, optimize
from bracing_experiments.optimize_specs import Problem, build_problem, check_metrics


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bracing-optimize", description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--config", required=True, type=Path, help="scenario params file")
    parser.add_argument("--vary", action="append", default=[], metavar="KEY=LOW:HIGH", help="a parameter and its range")
    parser.add_argument("--minimize", action="append", default=[], metavar="METRIC", help="an objective (summary key)")
    parser.add_argument("--subject-to", dest="subject_to", action="append", default=[], metavar="'METRIC<=V'")
    add_overrides(parser, "trial")
    parser.add_argument("--trials", type=int, default=100, help="trials in the study, resumed ones included")
    add_duration(parser, "trial")
    add_executor(parser)
    parser.add_argument("--seed", type=int, default=0, help="the sampler's seed")
    add_output(parser, "study")
    add_progress(parser)
    args = parser.parse_args(argv)
    if args.trials < 1:
        parser.error("--trials must be >= 1")
    check_options(parser, args)
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    resumes = f"finished trials kept in {args.output / STUDY_DB}, the same command again resumes"
    ran = run_command(
        "bracing-optimize",
        args,
        lambda: _checked_problem(args),
        lambda problem, executor: _run_trials(problem, executor, args),
        resumes,
    )
    if isinstance(ran, int):
        return ran
    print(summary_text(ran.built, ran.done, args.output))
    return EXIT_FAILED if ran.done.search.failed else 0


def _run_trials(problem: Problem, executor: Executor, args: argparse.Namespace) -> Optimum:
    """The study in --output run up to --trials on the executor, every output written."""
    print(f"bracing-optimize: up to {args.trials} trials on {executor.description}", file=sys.stderr)
    return optimize(problem, args.output, executor, args.trials, not args.no_progress, args.seed)


def _checked_problem(args: argparse.Namespace) -> Problem:
    """The problem, its metrics probed, and its directory's manifest (a directory holds one problem's study)."""
    problem = build_problem(args.config, args.vary, args.minimize, args.subject_to, args.duration, args.sets)
    check_metrics(problem)
    check_manifest(problem, args.output)
    return problem


def summary_text(problem: Problem, found: Optimum, output: Path) -> str:
    lines = [
        f"{found.trials} trials ({found.search.ran} now, {found.search.failed} failed now), "
        f"{found.search.wall_time_s:.1f} s; table: {output / TRIALS_CSV}; report: {output / REPORT}"
    ]
    if found.best is None:
        lines.append("no feasible trial")
    else:
        values = ", ".join(f"{k}={scenario_cell(v)}" for k, v in found.best.params.items())
        objectives = ", ".join(
            f"{m}={scenario_cell(v)}" for m, v in zip(problem.objectives, found.best.values, strict=True)
        )
        lines.append(f"best: trial {found.best.number}: {values}: {objectives}; scenario: {output / BEST_YAML}")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
