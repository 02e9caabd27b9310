"""bracing-study robustness: the paper's claims on a plant that differs from the controller's model, with
real sensing and late commands, with and without force feedback.

    bracing-study robustness --output DIR [--config FILE] [--seeds N] [--duration S]
                             [--workers N | --scheduler ADDRESS] [--no-progress] [--set KEY=VALUE ...]

The paper scenario (config/paper_4link.yaml; --config: another), braced, passive and in free space
(bracing_core.variants: make run's three runs), one factor at a time around the nominal (the controller's
model exact, exact sensing, no latency), not a full factorial:

- model error, in the simulated plant only: link masses and inertias x 0.7-1.3 (``plant_error.mass_scale``),
  the contact's mu 0.05-0.3 (``plant_error.friction_scale``; the paper's mu is 0.1), the motors' K and R
  x 0.9 and x 1.1 (``plant_error.torque_constant_scale``, ``plant_error.resistance_scale``);
- sensing: encoders of 4096 and 1024 counts per joint revolution, velocities differentiated from them
  (``sensors.encoder_counts_per_rev``, ``sensors.velocity_filter_hz``); a force sensor with 0.5 and 2 N of
  noise and a bias (``sensors.force_noise_n``, ``sensors.force_bias_n``);
- command latency: 1, 2 and 5 steps of the scenario's (1 ms) step (``sensors.command_latency_steps``);

each level with the paper's law and with force feedback on the braced contacts
(``contacts.<name>.force_feedback.kp`` / ``.ki``) plus thermal compensation of the voltage law
(``voltage_law.thermal_compensation``); passive and free runs have no braced contact, so they take the
thermal compensation only. In the scenario's input mode (voltage), and braced in torque mode too for the
model-error factors that apply to it (masses, friction).

Writes DIR/report.md (a table and a figure per factor, the nominal, and one generated paragraph: where
bracing still pays, and what force feedback buys), DIR/robustness_<factor>.png, DIR/runs.csv (one row per
condition and seed: bracing_experiments.study_runs), and the sweep's
DIR/results.parquet, DIR/results.csv and DIR/runs/ (the same command again reuses finished runs).
Exit 0 when every run is ok, 1 when one failed (the report is still written, its cells say which),
2 on a configuration error before any run (every run's configuration is checked first), 130 when
interrupted.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from bracing_core.overrides import parse_single
from bracing_core.params import ConfigError
from bracing_experiments.cli import (
    add_study_options,
    check_options,
    config_error,
    handle_stop_signals,
    interrupted,
    study_exit,
)
from bracing_experiments.executors import make_executor
from bracing_experiments.recorded import record_report
from bracing_experiments.reporting import resolve_scenario
from bracing_experiments.robustness_report import answer, late_force_rms, write_report
from bracing_experiments.robustness_specs import (
    BRACED,
    FEEDBACK_GAINS,
    FEEDBACK_LAW,
    FORCE_LATE,
    FREE_SPACE,
    LAW_TEXT,
    NOMINAL_LEVEL,
    PAPER_LAW,
    PASSIVE,
    STUDY,
    VARIANTS,
    build_robustness,
)
from bracing_experiments.study_runs import form_scenario
from bracing_experiments.sweep import ResultsStore, run_sweep

__all__ = [  # the study's names, wherever they live (its runs: robustness_specs; its report: robustness_report)
    "BRACED",
    "FEEDBACK_GAINS",
    "FEEDBACK_LAW",
    "FORCE_LATE",
    "FREE_SPACE",
    "LAW_TEXT",
    "NOMINAL_LEVEL",
    "PAPER_LAW",
    "PASSIVE",
    "STUDY",
    "VARIANTS",
    "answer",
    "build_robustness",
    "late_force_rms",
    "main",
    "write_report",
]


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog=f"bracing-study {STUDY}", description=(__doc__ or "").split("\n\n")[0].replace("\n", " ")
    )
    add_study_options(parser, exclusive_executors=True)
    args = parser.parse_args(argv)
    check_options(parser, args)
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    handle_stop_signals()
    start = time.perf_counter()
    name = f"bracing-study {STUDY}"
    try:
        config = resolve_scenario(form_scenario(args.config))
        study = build_robustness(config, args.duration, parse_single(args.sets), seeds=args.seeds)
        ResultsStore(args.output).check_manifest(config)
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        return config_error(name, exc)
    try:
        with executor:
            where = executor.description
            print(f"{name}: {len(study.specs)} runs of {config} on {where}", file=sys.stderr)
            result = run_sweep(study.specs, args.output, executor, progress=not args.no_progress)
    except KeyboardInterrupt:
        return interrupted(name)
    report = write_report(study, args.output, time.perf_counter() - start, where, result.skipped)
    record_report(report, STUDY, config)
    print(f"{name}: {result.ran} run now, {result.skipped} reused; report: {report}")
    return study_exit(name, result.rows, result.lost, args.output)


if __name__ == "__main__":
    sys.exit(main())
