"""bracing-optimize's recorded file, DIR/tables.json (bracing_experiments.recorded): its report's tables (the
optimum's parameters beside the file's, the runs beside each other) and a ``search`` table (the trials by status,
the sampler and its seed, the best trial, this invocation's time), with the date, commit and machine, so that a
results page renders the optimiser's answer from the run (tools/docs_reference.py) instead of typing it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bracing_experiments.recorded import TABLES_FILE, report_conclusions, report_tables, write_recorded

SEARCH_TABLE = "search"
"""The key of the one-row table of the search's facts (column -> cell, as ``search`` is given)."""


def record_optimisation(report: Path, config: Path, search: dict[str, Any]) -> Path:
    """``report``'s tables and bold-lead paragraphs with the ``search`` table (one row: ``search``'s values under
    its keys) as a recorded file beside the report."""
    text = report.read_text()
    tables = {SEARCH_TABLE: {"header": list(search), "rows": [[str(value) for value in search.values()]]}}
    content = {"study": "optimize", "config": config.name, "tables": {**tables, **report_tables(text)}}
    content["conclusions"] = report_conclusions(text)
    return write_recorded(report.parent / TABLES_FILE, content)
