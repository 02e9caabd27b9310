"""Runs on an executor into a results directory (every command's): DIR/runs/<run id>/ saved as each run
finishes, the table (results.parquet, results.csv) kept, finished runs reused, Ctrl-C keeping them."""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from bracing_core.params import ConfigError
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import STATUS_FAILED, STATUS_OK, RunOutcome, RunSpec, execute_run

ROW_FILE, SUMMARY_FILE, ARRAYS_FILE = "row.json", "summary.json", "arrays.npz"
RESULTS_PARQUET, RESULTS_CSV, MANIFEST = "results.parquet", "results.csv", "sweep.json"
ORDER_FIRST = ("run_id", "status", "error")
ORDER_LAST = ("wall_time_s", "worker", "traceback")


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
