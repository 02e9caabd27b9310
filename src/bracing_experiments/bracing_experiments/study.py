"""bracing-study: the paper's comparisons as one report, from in-process runs in parallel.

    bracing-study paper --output DIR [--config FILE] [--seeds N] [--duration S] [--workers N]
                        [--scheduler ADDRESS] [--set KEY=VALUE ...]
                        [--positions N] [--span M] [--trials N]
    bracing-study config/hyper_7link.yaml --output DIR
    bracing-study robustness --output DIR [--duration S] [--workers N | --scheduler ADDRESS] [--set KEY=VALUE ...]

``robustness`` is the robustness study (bracing_experiments.robustness: the paper scenario under model error,
real sensing and command latency, with and without force feedback; ``bracing-study robustness --help``); the
rest of this docstring is the paper study's.

1. bracing: braced vs passive (make run's: no brace task, the surfaces kept as obstacles the arm can
   rest on) vs free (no contacts), voltage and torque input, with and without null-space gravity
   compensation: hand RMS / max error, energy consumed, copper loss, the hottest motor;
2. gains: every PD gain (hand and brace, Kp and Kd) scaled by 1, 0.5, 0.2, 0.1, torque and
   voltage input: force error (max, RMS) against the position errors (paper Sec. 4, Figs. 9-16);
3. placement: energy and hand error over a grid of brace targets along the first brace axis of
   the first contact and of desired normal forces, the best cell marked; then bracing-optimize's
   search over the same two axes (least energy subject to a hand RMS bound; ``--trials N``), its
   optimum beside the grid's best cell, the file's setting and the passive run.

Writes DIR/report.md with its figures (bracing.png, gains.png, placement.png), and the sweep's
DIR/results.parquet, DIR/results.csv and DIR/runs/ (the same command again reuses finished runs), and
the optimiser's study in DIR/optimize/<problem>/ (study.db, trials.csv, best.yaml, report.md: the same
command again reuses its trials, and runs only those a larger --trials asks for).
Exit 0 when every run is ok, 1 when one failed (the report is still written, its cells say which),
2 on a configuration error before any run (every run's configuration and task rank are checked first).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from bracing_core.overrides import parse_single
from bracing_core.params import ConfigError
from bracing_experiments.cli import EXIT_FAILED, add_study_options, check_options, study_exit
from bracing_experiments.executors import Executor
from bracing_experiments.pays import main as pays_main
from bracing_experiments.pays_specs import STUDY as PAYS
from bracing_experiments.recorded import record_report
from bracing_experiments.reporting import resolve_scenario
from bracing_experiments.robustness import STUDY as ROBUSTNESS
from bracing_experiments.robustness import main as robustness_main
from bracing_experiments.running import ResultsStore
from bracing_experiments.study_cli import run_form
from bracing_experiments.study_report import write_report
from bracing_experiments.study_runs import DEFAULT_SCENARIO, form_scenario
from bracing_experiments.study_specs import (
    PAPER_HAND_RMS_BOUND,
    SEARCH_TRIALS,
    PlacementSearch,
    Study,
    build_study,
    placement_search,
    run_placement_search,
)

COMMAND = "bracing-study"

__all__ = [  # the study's names, wherever they live (its runs: study_specs; its report: study_report)
    "PAPER_HAND_RMS_BOUND",
    "build_study",
    "main",
    "placement_search",
    "resolve_scenario",
    "run_placement_search",
    "write_report",
]


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bracing-study", description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument(
        "scenario",
        help=f"'paper': the paper study, on --config's scenario (default the paper's); a scenario params file: the "
        f"same as paper --config FILE; '{ROBUSTNESS}': the robustness study ({ROBUSTNESS} --help); '{PAYS}': when "
        f"bracing pays ({PAYS} --help)",
    )
    add_study_options(parser)
    parser.add_argument("--positions", type=int, default=5, help="brace targets in the placement grid")
    parser.add_argument("--span", type=float, default=0.15, help="placement targets: start position +- span [m]")
    parser.add_argument(
        "--trials",
        type=int,
        default=SEARCH_TRIALS,
        help=f"the optimiser's trials over the placement axes (default {SEARCH_TRIALS}; 0: no search)",
    )
    args = parser.parse_args(argv)
    if args.trials < 0:
        parser.error("--trials must be >= 0")
    check_options(parser, args)  # (--workers >= 1: checked since the options are one with the other commands')
    if args.positions < 1 or args.span < 0:
        parser.error("--positions must be >= 1 and --span >= 0")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == [ROBUSTNESS]:  # its own options (bracing_experiments.robustness)
        return robustness_main(argv[1:])
    if argv[:1] == [PAYS]:  # its own options (bracing_experiments.pays)
        return pays_main(argv[1:])
    args = parse_args(argv)
    ran = run_form(COMMAND, args, lambda: _checked_study(args), lambda study, executor: _search(study, args, executor))
    if isinstance(ran, int):
        return ran
    search, note = ran.after
    report = write_report(ran.study, args.output, ran.wall_time_s, ran.where, ran.sweep.skipped, search, note)
    record_report(report, "paper", ran.config)
    found = search.found if search is not None else None
    trials = f"; optimiser: {found.trials} trials ({found.search.ran} now)" if found is not None else ""
    print(f"{COMMAND}: {ran.sweep.ran} run now, {ran.sweep.skipped} reused{trials}; report: {report}")
    code = study_exit(COMMAND, ran.sweep.rows, ran.sweep.lost, args.output)
    return code or (EXIT_FAILED if found is not None and found.search.failed else 0)


def _checked_study(args: argparse.Namespace) -> tuple[Path, Study]:
    """The scenario file and the study's runs, every one checked, and the directory's manifest."""
    given = None if args.scenario == DEFAULT_SCENARIO else args.scenario
    config = resolve_scenario(form_scenario(args.config, given))
    overrides = parse_single(args.sets)
    study = build_study(config, args.duration, overrides, args.positions, args.span, seeds=args.seeds)
    ResultsStore(args.output).check_manifest(config)
    return config, study


def _search(study: Study, args: argparse.Namespace, executor: Executor) -> tuple[PlacementSearch | None, str]:
    """After the grid: the optimiser's search over its axes (--trials; 0: none), and a note when none ran."""
    if args.trials == 0:
        return None, "--trials 0"
    rows = study.replicas.median_rows(ResultsStore(args.output))
    try:
        search = placement_search(study, rows, args.output)
    except ConfigError as exc:
        print(f"{COMMAND}: no optimisation: {exc}", file=sys.stderr)
        return None, str(exc)
    run_placement_search(search, executor, args.trials, progress=not args.no_progress)
    return search, ""


if __name__ == "__main__":
    sys.exit(main())
