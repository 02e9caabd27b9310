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
from collections.abc import Sequence
from pathlib import Path

from bracing_core.overrides import parse_single
from bracing_experiments.cli import add_study_options, check_options, study_exit
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
    Robustness,
    build_robustness,
)
from bracing_experiments.running import ResultsStore
from bracing_experiments.study_cli import run_form
from bracing_experiments.study_runs import form_scenario

COMMAND = f"bracing-study {STUDY}"

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
    ran = run_form(COMMAND, args, lambda: _checked_study(args), lambda study, executor: None)
    if isinstance(ran, int):
        return ran
    report = write_report(ran.study, args.output, ran.wall_time_s, ran.where, ran.sweep.skipped)
    record_report(report, STUDY, ran.config)
    print(f"{COMMAND}: {ran.sweep.ran} run now, {ran.sweep.skipped} reused; report: {report}")
    return study_exit(COMMAND, ran.sweep.rows, ran.sweep.lost, args.output)


def _checked_study(args: argparse.Namespace) -> tuple[Path, Robustness]:
    """The scenario file and the study's runs, every one checked, and the directory's manifest."""
    config = resolve_scenario(form_scenario(args.config))
    study = build_robustness(config, args.duration, parse_single(args.sets), seeds=args.seeds)
    ResultsStore(args.output).check_manifest(config)
    return config, study


if __name__ == "__main__":
    sys.exit(main())
