"""bracing-sweep: a scenario over a grid of parameter values, in-process runs in parallel.

    bracing-sweep --config F --set KEY=V1,V2,... [--set ...] [--zip] [--duration S]
                  [--workers N] [--scheduler ADDRESS] --output DIR

Every combination of the --set values (or, with --zip, the i-th value of every key together)
is one run of the nodes' core objects in one process (bracing_core.rollout), on local
worker processes, or on a Dask cluster with --scheduler tcp://HOST:PORT (``local``: a Dask
LocalCluster on this machine). Writes DIR/runs/<run id>/{row.json,summary.json,arrays.npz}
as each run finishes and DIR/results.parquet + DIR/results.csv, one row per run. A failing
run is a row with its error; Ctrl-C keeps every finished row; the same command again skips
the runs already done. Every run's configuration is checked before the first starts, the task's
rank at the start posture too (as a run checks it). Exit 0 when every run is ok, 1 when one failed
(the table is still written), 2 on a configuration error before any run, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import os
import re
import secrets
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from bracing_core.config import Plant, project_initial_position
from bracing_core.controller_config import ControllerConfig
from bracing_core.law import check_task_rank
from bracing_core.overrides import (
    CONTROLLER,
    NodeOverrides,
    format_value,
    node_params,
    parse_sweep,
    route,
    validate,
)
from bracing_core.params import ConfigError
from bracing_experiments.cli import (
    EXIT_FAILED,
    add_duration,
    add_executor,
    add_output,
    add_progress,
    check_options,
    failed_runs,
    run_command,
)
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import STATUS_FAILED, STATUS_OK, RunOutcome, RunSpec, execute_run

if TYPE_CHECKING:
    from bracing_core.config import SimulatorConfig

ROW_FILE, SUMMARY_FILE, ARRAYS_FILE = "row.json", "summary.json", "arrays.npz"
RESULTS_PARQUET, RESULTS_CSV, MANIFEST = "results.parquet", "results.csv", "sweep.json"
ORDER_FIRST = ("run_id", "status", "error")
ORDER_LAST = ("wall_time_s", "worker", "traceback")


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


def run_id(varied: dict[str, Any], duration: float, overrides: dict[str, Any] | None = None) -> str:
    """Stable, readable and unique: the varied values in a short slug plus a hash of everything that
    makes the run (``overrides``: the parameters applied, when they are not the varied values)."""
    canonical = json.dumps({"varied": varied, "overrides": overrides, "duration": duration}, sort_keys=True)
    digest = hashlib.sha1(canonical.encode()).hexdigest()[:10]
    slug = "-".join(f"{key}={format_value(value)}" for key, value in varied.items())
    slug = re.sub(r"[^A-Za-z0-9_=.+-]+", "-", slug.replace("[", "").replace("]", "").replace(",", "+"))
    slug = slug.strip("-")[:80]
    return f"{slug}-{digest}" if slug else digest


def make_spec(
    config: Path,
    varied: dict[str, Any],
    duration: float | None = None,
    labels: dict[str, Any] | None = None,
    overrides: dict[str, Any] | None = None,
) -> RunSpec:
    """One run's spec, validated: a ConfigError names the parameter. ``overrides``: flat parameters
    applied (default: ``varied`` itself; a study labels its runs differently)."""
    node_overrides: NodeOverrides = route(varied if overrides is None else overrides)
    sim_config = validate(config, node_overrides)
    run_duration = duration if duration is not None else sim_config.duration
    if run_duration <= 0:
        raise ConfigError("duration: a sweep run needs a duration > 0 (set it in the file, --set or --duration)")
    params = node_params(config, node_overrides)
    check_task_rank_at_start(sim_config, params[CONTROLLER], config, node_overrides)
    urdf = sim_config.shared.urdf  # resolved now, against the config's directory
    for node in params.values():
        node["robot.urdf"] = str(urdf)
    return RunSpec(
        run_id=run_id(varied, run_duration, overrides),
        varied=dict(varied),
        sim_params=params["bracing_simulator"],
        ctl_params=params["bracing_controller"],
        duration=run_duration,
        urdf_text=urdf.read_text(),
        labels=dict(labels or {}),
    )


def check_task_rank_at_start(
    sim_config: SimulatorConfig, ctl_params: dict[str, Any], config: Path, node_overrides: NodeOverrides
) -> None:
    """A run's task-rank check (``bracing_core.law.check_task_rank``, at the start posture, as
    ``rollout.build_scenario_from_params`` runs it) before any run: a task direction the arm cannot
    move along is the scenario's error, not one run's. ConfigError names it and the overrides. A start
    the projection cannot make feasible is left to the run (a failed row, as before)."""
    try:
        plant = Plant(sim_config.shared, sim_config.slip_epsilon)
        controller = ControllerConfig.from_params(ctl_params, [config.resolve().parent])
        start = plant.to_model_order(sim_config.initial_position)
        if sim_config.project_initial_position:
            try:
                start = project_initial_position(plant, start)
            except ConfigError:
                return  # the run says so itself
        check_task_rank(controller, plant, start)
    except ConfigError as exc:
        given = ", ".join(f"{k}={format_value(v)}" for k, v in node_overrides.flat().items())
        raise ConfigError(f"{exc}" + (f" (with --set {given})" if given else "")) from None


def table_value(value: Any) -> Any:
    return json.dumps(value) if isinstance(value, (list, dict)) else value


class ResultsStore:
    """DIR/runs/<id>/ per run (row.json written last: its presence means done), and the table."""

    def __init__(self, output: Path) -> None:
        self.output = output
        self.runs = output / "runs"

    def run_dir(self, run_id: str) -> Path:
        return self.runs / run_id

    def row(self, run_id: str) -> dict[str, Any] | None:
        try:
            row: dict[str, Any] = json.loads((self.run_dir(run_id) / ROW_FILE).read_text())
        except (OSError, ValueError):
            return None
        return row

    def check_manifest(self, config: Path) -> None:
        """One output directory holds sweeps of one scenario file (its content): a resumed run
        must not mix rows of another scenario."""
        manifest = self.output / MANIFEST
        digest = hashlib.sha1(config.read_bytes()).hexdigest()
        current = {"config": str(config.resolve()), "config_sha1": digest}
        if manifest.is_file():
            previous = json.loads(manifest.read_text())
            if previous.get("config_sha1") != digest:
                raise ConfigError(
                    f"--output {self.output}: holds runs of another scenario ({previous.get('config')}, "
                    "different content); choose a new output directory"
                )
        self.output.mkdir(parents=True, exist_ok=True)
        _write_atomic(manifest, json.dumps(current, indent=2) + "\n")

    def save(self, outcome: RunOutcome) -> None:
        folder = self.run_dir(str(outcome.row["run_id"]))
        folder.mkdir(parents=True, exist_ok=True)
        if outcome.arrays is not None:
            _write_atomic(folder / ARRAYS_FILE, outcome.arrays)
        if outcome.summary is not None:
            _write_atomic(folder / SUMMARY_FILE, json.dumps(outcome.summary, indent=2) + "\n")
        _write_atomic(folder / ROW_FILE, json.dumps(outcome.row, indent=2) + "\n")

    def write_table(self, run_ids: Sequence[str], leading: Sequence[str] = ()) -> list[dict[str, Any]]:
        """results.parquet and results.csv from the finished rows of ``run_ids`` (in that order);
        columns: run_id, status, error, ``leading`` (the varied values), the metrics, wall time."""
        rows = [row for row in (self.row(i) for i in run_ids) if row is not None]
        write_tables(self.output, rows, leading, RESULTS_PARQUET, RESULTS_CSV)
        return rows


def write_tables(output: Path, rows: Sequence[dict[str, Any]], leading: Sequence[str], parquet: str, csv: str) -> None:
    """``rows`` as ``output/parquet`` and ``output/csv`` (each replaced atomically); columns: run_id,
    status, error, ``leading``, the rest in first-seen order, wall time and worker last. A column
    mixing kinds (numbers and text) is written as text. Shared by sweeps and the optimiser."""
    import pyarrow as pa  # imported where used: pyarrow ~200 ms (python -X importtime)
    import pyarrow.csv as pa_csv  # imported where used: pyarrow ~200 ms (python -X importtime)
    import pyarrow.parquet as pq  # imported where used: pyarrow ~200 ms (python -X importtime)

    columns: list[str] = []
    for row in rows:
        columns += [key for key in row if key not in columns]
    first = [c for c in (*ORDER_FIRST, *leading) if c in columns]
    columns = (
        list(dict.fromkeys(first))
        + [c for c in columns if c not in first and c not in ORDER_LAST]
        + [c for c in ORDER_LAST if c in columns]
    )
    data: dict[str, list[Any]] = {c: [table_value(row.get(c)) for row in rows] for c in columns}
    arrays = {}
    for name, values in data.items():
        try:
            arrays[name] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):  # mixed kinds in one column: as text
            arrays[name] = pa.array([None if v is None else str(v) for v in values], pa.string())
    table = pa.table(arrays) if arrays else pa.table({"run_id": pa.array([], pa.string())})
    output.mkdir(parents=True, exist_ok=True)
    for name, write in ((parquet, pq.write_table), (csv, pa_csv.write_csv)):
        temporary = output / f".{name}.tmp"
        write(table, str(temporary))
        os.replace(temporary, output / name)


def _write_atomic(path: Path, content: str | bytes) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    if isinstance(content, bytes):
        temporary.write_bytes(content)
    else:
        temporary.write_text(content)
    os.replace(temporary, path)


@dataclass
class SweepResult:
    rows: list[dict[str, Any]]  # the table: finished rows of this sweep, in spec order
    ran: int = 0  # runs executed now
    skipped: int = 0  # already done before
    failed: int = 0  # rows with an error (now)
    lost: list[str] = field(default_factory=list)  # run ids the executor could not finish (retried next time)
    interrupted: bool = False
    wall_time_s: float = 0.0


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during a sweep, after every finished row was saved and the table written."""

    def __init__(self, result: SweepResult) -> None:
        super().__init__("sweep interrupted")
        self.result = result


def run_sweep(
    specs: Sequence[RunSpec],
    output: Path,
    executor: Executor,
    *,
    retry_failed: bool = False,
    progress: bool = True,
    on_outcome: Callable[[RunOutcome], None] | None = None,
    table_interval_s: float = 2.0,
) -> SweepResult:
    """Run what is not done yet; rows are saved as they arrive, the table at least every
    ``table_interval_s`` and at the end, also after Ctrl-C, which then raises SweepInterrupted."""
    start = time.perf_counter()
    store = ResultsStore(output)
    ids = list(dict.fromkeys(spec.run_id for spec in specs))  # a study may list a run twice
    varied = list(dict.fromkeys(key for spec in specs for key in (*spec.labels, *spec.varied)))
    unique = {spec.run_id: spec for spec in specs}
    pending = []
    for run in ids:
        row = store.row(run)
        if row is None or (retry_failed and row.get("status") != STATUS_OK):
            pending.append(unique[run])
    result = SweepResult(rows=[], skipped=len(ids) - len(pending))
    token = secrets.token_hex(4)  # Dask task keys: unique per invocation, readable per run
    bar = tqdm(total=len(pending), unit="run", desc="sweep", disable=not progress, dynamic_ncols=True)
    last_table = time.monotonic()
    try:
        outcomes = executor.run(execute_run, pending, keys=[f"bracing-{s.run_id}-{token}" for s in pending])
        for spec, outcome, error in outcomes:
            if error is not None or outcome is None:
                result.lost.append(spec.run_id)
                bar.write(
                    f"run {spec.run_id}: not finished by the executor: {type(error).__name__}: {error}", sys.stderr
                )
            else:
                store.save(outcome)
                result.ran += 1
                if outcome.row.get("status") == STATUS_FAILED:
                    result.failed += 1
                    bar.write(f"run {spec.run_id} failed: {outcome.row.get('error')}", sys.stderr)
                if on_outcome is not None:
                    on_outcome(outcome)
            bar.update(1)
            bar.set_postfix(failed=result.failed + len(result.lost), refresh=False)
            if time.monotonic() - last_table >= table_interval_s:
                store.write_table(ids, varied)
                last_table = time.monotonic()
    except KeyboardInterrupt as interrupt:
        result.interrupted = True
        executor.cancel()
        result.rows = store.write_table(ids, varied)
        result.wall_time_s = time.perf_counter() - start
        raise SweepInterrupted(result) from interrupt
    finally:
        bar.close()
    result.rows = store.write_table(ids, varied)
    result.wall_time_s = time.perf_counter() - start
    return result


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
    add_progress(parser)
    args = parser.parse_args(argv)
    check_options(parser, args)
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


def row_warnings(rows: Sequence[dict[str, Any]]) -> dict[str, int]:
    """Each distinct warning of the rows' summaries (their ``warnings`` column: JSON), and in how many runs."""
    counts: dict[str, int] = {}
    for row in rows:
        try:
            warnings = json.loads(row.get("warnings") or "[]")
        except (TypeError, ValueError):
            continue
        for text in dict.fromkeys(warnings if isinstance(warnings, list) else []):
            counts[str(text)] = counts.get(str(text), 0) + 1
    return counts


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    ran = run_command(
        "bracing-sweep", args, lambda: _checked_specs(args), lambda specs, executor: _sweep(specs, executor, args), None
    )
    if isinstance(ran, int):
        return ran
    result = ran.done
    print(outcome_text(result, args.output, len(ran.built)))
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
