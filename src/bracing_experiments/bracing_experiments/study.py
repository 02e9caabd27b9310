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
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from bracing_core.overrides import parse_single
from bracing_core.params import ConfigError
from bracing_experiments.cli import (
    EXIT_FAILED,
    add_study_options,
    check_options,
    config_error,
    handle_stop_signals,
    interrupted,
    study_exit,
)
from bracing_experiments.executors import make_executor
from bracing_experiments.pays import STUDY as PAYS
from bracing_experiments.pays import main as pays_main
from bracing_experiments.recorded import record_report
from bracing_experiments.reporting import resolve_scenario
from bracing_experiments.robustness import STUDY as ROBUSTNESS
from bracing_experiments.robustness import main as robustness_main
from bracing_experiments.study_runs import DEFAULT_SCENARIO, form_scenario
from bracing_experiments.sweep import ResultsStore, run_sweep

if TYPE_CHECKING:
    pass
from bracing_experiments.study_report import write_report
from bracing_experiments.study_specs import (
    PAPER_HAND_RMS_BOUND,
    SEARCH_TRIALS,
    build_study,
    placement_search,
    run_placement_search,
)

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
    handle_stop_signals()
    start = time.perf_counter()
    try:
        given = None if args.scenario == DEFAULT_SCENARIO else args.scenario
        config = resolve_scenario(form_scenario(args.config, given))
        overrides = parse_single(args.sets)
        study = build_study(config, args.duration, overrides, args.positions, args.span, seeds=args.seeds)
        ResultsStore(args.output).check_manifest(config)
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        return config_error("bracing-study", exc)
    try:
        with executor:
            where = executor.description
            print(f"bracing-study: {len(study.specs)} runs of {config} on {where}", file=sys.stderr)
            result = run_sweep(study.specs, args.output, executor, progress=not args.no_progress)
            search, note = None, "--trials 0" if args.trials == 0 else ""
            if args.trials > 0:
                rows = study.replicas.median_rows(ResultsStore(args.output))
                try:
                    search = placement_search(study, rows, args.output)
                except ConfigError as exc:
                    note = str(exc)
                    print(f"bracing-study: no optimisation: {note}", file=sys.stderr)
                if search is not None:
                    run_placement_search(search, executor, args.trials, progress=not args.no_progress)
    except KeyboardInterrupt:
        return interrupted("bracing-study")
    report = write_report(study, args.output, time.perf_counter() - start, where, result.skipped, search, note)
    record_report(report, "paper", config)
    found = search.found if search is not None else None
    trials = f"; optimiser: {found.trials} trials ({found.search.ran} now)" if found is not None else ""
    print(f"bracing-study: {result.ran} run now, {result.skipped} reused{trials}; report: {report}")
    code = study_exit("bracing-study", result.rows, result.lost, args.output)
    return code or (EXIT_FAILED if found is not None and found.search.failed else 0)


if __name__ == "__main__":
    sys.exit(main())
