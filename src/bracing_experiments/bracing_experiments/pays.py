"""bracing-study pays: when does bracing pay, by how much, and how sure is it.

    bracing-study pays --output DIR [--config FILE] [--seeds N] [--duration S] [--workers N | --scheduler ADDRESS]
                       [--forces F1,F2,...] [--positions N] [--span M] [--trials N] [--set KEY=VALUE ...]

Bracing against resting passively (bracing_core.variants.PASSIVE: no brace task, the surfaces kept as obstacles
the arm may rest on) and against free space (FREE_SPACE), over the desired normal force f_nd and the brace
place (the first braced contact's target along its first brace axis, the file's +- ``--span``; an arm whose
brace has no brace axis, such as the shipped UR5, varies f_nd only), under realistic conditions (``REALISTIC``:
the robustness study's sensing levels at once and a plant whose link masses differ from the controller's model by
a draw of the seed), each seed its own draw and noise. Then bracing-optimize searches the same axes for the
least energy at a hand error no worse than resting passively (the first seed's conditions; Optuna's TPE, its
sampler seeded), and its optimum is run again on every seed.

A cell pays on energy (on accuracy) in a seed when its braced run uses less energy (has a smaller hand RMS
error, t >= 2 s) than the passive run of the same seed; the report gives every ratio as a median with its spread
over the seeds (the range; 10-90 % with 10 seeds or more) and each conclusion with the number of cells and seeds
it holds in. Writes DIR/report.md, DIR/runs.csv (one row per run: condition, seed, f_nd, place, every metric),
DIR/tables.json (the report's tables, recorded: bracing_experiments.recorded) and the sweep's files.
Exit 0 when every run is ok, 1 when one failed, 2 on a configuration error before any run.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bracing_core.numbers import number
from bracing_core.overrides import parse_single
from bracing_experiments.cli import add_study_options, check_options, study_exit
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import RunSpec
from bracing_experiments.optimize_search import Optimum, optimize
from bracing_experiments.optimize_specs import Problem
from bracing_experiments.pays_report import write_report, write_runs
from bracing_experiments.pays_specs import (
    ENERGY,
    HAND_RMS,
    SEARCH_DIR,
    SEARCH_SEED,
    STUDY,
    Pays,
    build_pays,
    optimum_specs,
    search_problem,
)
from bracing_experiments.recorded import record_report
from bracing_experiments.reporting import is_ok, resolve_scenario
from bracing_experiments.running import ResultsStore, SweepResult, run_sweep
from bracing_experiments.study_cli import run_form
from bracing_experiments.study_runs import form_scenario

COMMAND = f"bracing-study {STUDY}"
_AfterGrid = tuple[Optimum | None, str, list[RunSpec], SweepResult | None]
"""What runs after the grid: the optimum found, the search's note, the optimum's runs and their sweep."""


def run_search(
    study: Pays, output: Path, executor: Any, trials: int, progress: bool
) -> tuple[Problem | None, Optimum | None, str]:
    """The optimiser's search (after the grid: its bound is the first seed's passive hand RMS)."""
    passive = ResultsStore(output).row(study.specs[0].run_id)
    if trials == 0:
        return None, None, "Not run (--trials 0)."
    if passive is None or not is_ok(passive) or not number(passive.get(HAND_RMS)):
        return None, None, "Not run: the first seed's passive run has no hand RMS error (a run of >= 2 s needed)."
    bound = float(passive[HAND_RMS])
    problem = search_problem(study, bound)
    found = optimize(
        problem, output / SEARCH_DIR / problem.key, executor, trials, progress, SEARCH_SEED, references=False
    )
    varied = ", ".join(v.flag for v in problem.varies)
    note = (
        f"bracing-optimize (Optuna's TPE, sampler seed {SEARCH_SEED}, {found.trials} trials, in seed "
        f"{study.seeds[0]}'s conditions): least `{ENERGY}` subject to `{HAND_RMS}` <= {bound * 1e3:.4g} mm (the "
        f"passive run's of that seed), over {varied}; its study: `{SEARCH_DIR}/{problem.key}/`. "
    )
    note += "Its optimum is run again in every seed (the `optimum` rows)." if found.best else "No feasible trial."
    return problem, found, note


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"bracing-study {STUDY}", description=(__doc__ or "").split("\n\n")[0])
    add_study_options(parser, exclusive_executors=True)
    parser.add_argument(
        "--forces", default="", help="f_nd of the grid [N], comma-separated (default x 0.5, 1, 2, 3 the file's)"
    )
    parser.add_argument("--positions", type=int, default=5, help="brace places in the grid (an arm with a brace axis)")
    parser.add_argument("--span", type=float, default=0.15, help="brace places: the file's +- span [m]")
    parser.add_argument("--trials", type=int, default=30, help="the optimiser's trials (default 30; 0: no search)")
    args = parser.parse_args(argv)
    check_options(parser, args)
    if args.trials < 0 or args.positions < 1 or args.span < 0:
        parser.error("--positions must be >= 1, --trials and --span >= 0")
    try:
        args.force_list = [float(f) for f in args.forces.split(",")] if args.forces else []
    except ValueError:
        parser.error(f"--forces: numbers separated by commas, not {args.forces!r}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    ran = run_form(COMMAND, args, lambda: _checked_study(args), lambda study, executor: _search(study, args, executor))
    if isinstance(ran, int):
        return ran
    found, note, again, rerun = ran.after
    specs = [*ran.study.specs, *again]
    report = write_report(ran.study, specs, args.output, found, note)
    write_runs(specs, ResultsStore(args.output), args.output)
    record_report(report, STUDY, ran.config)
    print(f"{COMMAND}: {ran.sweep.ran} run now, {ran.sweep.skipped} reused; report: {report}")
    rows = [*ran.sweep.rows, *(rerun.rows if rerun else [])]
    return study_exit(COMMAND, rows, [*ran.sweep.lost, *(rerun.lost if rerun else [])], args.output)


def _checked_study(args: argparse.Namespace) -> tuple[Path, Pays]:
    """The scenario file and the study's runs, every one checked, and the directory's manifest."""
    config = resolve_scenario(form_scenario(args.config))
    study = build_pays(
        config, args.seeds, args.duration, parse_single(args.sets), args.force_list, args.positions, args.span
    )
    ResultsStore(args.output).check_manifest(config)
    return config, study


def _search(study: Pays, args: argparse.Namespace, executor: Executor) -> _AfterGrid:
    """After the grid: the optimiser's search, then its optimum run again in every seed."""
    progress = not args.no_progress
    problem, found, note = run_search(study, args.output, executor, args.trials, progress)
    again = optimum_specs(study, problem, found) if problem is not None and found is not None else []
    rerun = run_sweep(again, args.output, executor, progress=progress) if again else None
    return found, note, again, rerun
