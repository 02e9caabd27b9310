"""bracing-sweep: a scenario over a grid of parameter values, in-process runs in parallel.

    bracing-sweep --config F --set KEY=V1,V2,... [--set ...] [--zip] [--duration S]
                  [--workers N] [--scheduler ADDRESS] --output DIR [--record FILE --columns A,B,...]

Every combination of the --set values (or, with --zip, the i-th value of every key together)
is one run of the nodes' core objects in one process (bracing_core.rollout), on local
worker processes, or on a Dask cluster with --scheduler tcp://HOST:PORT (``local``: a Dask
LocalCluster on this machine). Writes DIR/runs/<run id>/{row.json,summary.json,arrays.npz}
as each run finishes and DIR/results.parquet + DIR/results.csv, one row per run. A failing
run is a row with its error; Ctrl-C keeps every finished row; the same command again skips
the runs already done. ``--record FILE --columns A,B,...``: the table's varied values and those
metrics also as a recorded file (bracing_experiments.sweep_record: with the date, commit and machine).
Every run's configuration is checked before the first starts, the task's rank at the start posture
too (as a run checks it). Exit 0 when every run is ok, 1 when one failed
(the table is still written), 2 on a configuration error before any run, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bracing_core.overrides import parse_sweep
from bracing_core.params import ConfigError
from bracing_experiments.cli import (
    EXIT_FAILED,
    add_duration,
    add_executor,
    add_output,
    add_progress,
    check_options,
    config_error,
    failed_runs,
    run_command,
)
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import STATUS_OK, RunSpec
from bracing_experiments.running import (
    RESULTS_CSV,
    RESULTS_PARQUET,
    ResultsStore,
    SweepInterrupted,
    SweepResult,
    row_warnings,
    run_sweep,
)
from bracing_experiments.specs import make_spec
from bracing_experiments.sweep_record import parse_columns, record_sweep, unknown_columns


def combinations(values: dict[str, list[Any]], zipped: bool = False) -> list[dict[str, Any]]:
    """The runs' varied values: the grid (first key slowest), or the lists side by side (--zip)."""
    keys = list(values)
    if not keys:
        return [{}]
    if zipped:
        lengths = {key: len(v) for key, v in values.items()}
        if len(set(lengths.values())) != 1:
            listed = ", ".join(f"{k} has {n}" for k, n in lengths.items())
            raise ConfigError(f"--zip: every --set needs the same number of values ({listed})")
        return [dict(zip(keys, combo, strict=True)) for combo in zip(*values.values(), strict=True)]
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*values.values())]


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="bracing-sweep",
        description=(__doc__ or "").split("\n\n")[0],
        epilog=(
            "--set KEY=V1,V2,...: KEY is a flat scenario parameter (input_mode, hand.kp, "
            "contacts.elbow.desired_normal_force, gravity_compensation, duration, ...); values are YAML, "
            "separated by commas outside brackets: --set input_mode=voltage,torque --set 'hand.kp=[300,300],[150,150]' "
            "--set 'contacts.names=[elbow],[]' (bracing, no bracing)."
        ),
    )
    parser.add_argument("--config", required=True, type=Path, help="scenario params file")
    parser.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=V1,V2,...")  # values swept
    parser.add_argument("--zip", action="store_true", help="pair the i-th values of every --set (default: grid)")
    add_duration(parser)
    add_executor(parser)
    add_output(parser, "sweep")
    parser.add_argument("--retry-failed", action="store_true", help="run again the runs that failed before")
    parser.add_argument("--record", type=Path, metavar="FILE", help="also write the table as a recorded file (JSON)")
    parser.add_argument("--columns", type=parse_columns, metavar="A,B,...", help="--record's metrics, in order")
    add_progress(parser)
    args = parser.parse_args(argv)
    check_options(parser, args)
    if (args.record is None) != (args.columns is None):
        parser.error("--record and --columns go together")
    return args


def build_specs(config: Path, sets: Sequence[str], zipped: bool, duration: float | None) -> list[RunSpec]:
    """Every run's spec, each validated before any runs (ConfigError names the key)."""
    if not config.is_file():
        raise ConfigError(f"--config: file not found: {config}")
    return [make_spec(config, varied, duration) for varied in combinations(parse_sweep(sets), zipped)]


def _checked_specs(args: argparse.Namespace) -> list[RunSpec]:
    """The sweep's specs, checked, and its directory's manifest (a directory holds one scenario's runs)."""
    specs = build_specs(args.config, args.sets, args.zip, args.duration)
    ResultsStore(args.output).check_manifest(args.config)
    return specs


def outcome_text(result: SweepResult, output: Path, total: int) -> str:
    """What bracing-sweep prints at its end: the runs in the table, where it is, what to do next, the warnings."""
    ok = sum(1 for row in result.rows if row.get("status") == STATUS_OK)
    failed = failed_runs(result.rows)
    lines = [
        f"{len(result.rows)} of {total} runs in the table ({ok} ok, {failed} failed); "
        f"{result.ran} run now, {result.skipped} done before, {result.wall_time_s:.1f} s",
        f"table: {output / RESULTS_PARQUET}, {output / RESULTS_CSV}; runs: {output / 'runs'}",
    ]
    if result.lost:
        lines.append(f"{len(result.lost)} run(s) lost by the executor; the same command again retries them")
    if result.interrupted:
        lines.append("interrupted: the same command again runs the rest")
    lines += [f"warning ({runs} run(s)): {text}" for text, runs in row_warnings(result.rows).items()]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    ran = run_command(
        "bracing-sweep", args, lambda: _checked_specs(args), lambda specs, executor: _sweep(specs, executor, args), None
    )
    if isinstance(ran, int):
        return ran
    result = ran.done
    print(outcome_text(result, args.output, len(ran.built)))
    if args.record is not None:
        if unknown := unknown_columns(result.rows, args.columns):
            return config_error("bracing-sweep", ConfigError(f"--columns: not a metric of a run: {', '.join(unknown)}"))
        varied = list(dict.fromkeys(key for spec in ran.built for key in spec.varied))
        print(f"recorded: {record_sweep(args.record, args.config, result.rows, varied, args.columns)}")
    return EXIT_FAILED if result.lost or failed_runs(result.rows) else 0


def _sweep(specs: list[RunSpec], executor: Executor, args: argparse.Namespace) -> SweepResult:
    """The sweep on the executor; on Ctrl-C (after the first run was submitted) what is in the table, said."""
    print(f"bracing-sweep: {len(specs)} runs on {executor.description}", file=sys.stderr)
    try:
        return run_sweep(specs, args.output, executor, retry_failed=args.retry_failed, progress=not args.no_progress)
    except SweepInterrupted as interrupt:
        print(outcome_text(interrupt.result, args.output, len(specs)), file=sys.stderr)
        raise


if __name__ == "__main__":
    sys.exit(main())
