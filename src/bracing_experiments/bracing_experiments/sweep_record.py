"""A sweep's table as a recorded file (``bracing-sweep --record FILE --columns ...``): one row per run, the varied
values then the chosen metrics, with the date, commit and machine (bracing_experiments.recorded), so that a results
page renders a set of runs from the runs (tools/docs_reference.py) instead of typing their figures."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bracing_core.numbers import cell
from bracing_experiments.experiment import STATUS_OK
from bracing_experiments.recorded import write_recorded

RUNS_TABLE = "runs"
"""The recorded table's key."""


def parse_columns(text: str) -> list[str]:
    """``--columns A,B,...``: metrics as a sweep's table names them (dotted for a contact's)."""
    columns = [name.strip() for name in text.split(",") if name.strip()]
    if not columns:
        raise ValueError("--columns: no metric named")
    return columns


def unknown_columns(rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> list[str]:
    """The columns no finished run has (a misspelt metric)."""
    ok = [row for row in rows if row.get("status") == STATUS_OK]
    return [name for name in columns if ok and not any(name in row for row in ok)]


def run_cells(row: dict[str, Any], varied: Sequence[str], columns: Sequence[str]) -> list[str]:
    """One run's row: its varied values, then its metrics (4 significant digits, n/a for none); a failed run's
    first metric cell is its error."""
    values = [cell(row.get(key)) for key in varied]
    if row.get("status") != STATUS_OK:
        return [*values, f"failed: {row.get('error')}", *([""] * (len(columns) - 1))]
    return [*values, *(cell(row.get(name)) for name in columns)]


def record_sweep(
    path: Path, config: Path, rows: Sequence[dict[str, Any]], varied: Sequence[str], columns: Sequence[str]
) -> Path:
    """The runs' table as the recorded file ``path``: {"study": "sweep", "config", "tables": {"runs": ...}}."""
    table = {"header": [*varied, *columns], "rows": [run_cells(row, varied, columns) for row in rows]}
    content = {"study": "sweep", "config": config.name, "tables": {RUNS_TABLE: table}}
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_recorded(path, content)
