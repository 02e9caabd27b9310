"""What bracing-study's reports share (the paper study, ``study``, and the robustness study, ``robustness``):
the scenario by name, a run's row and arrays as a sweep stored them, a ratio of two runs' metric, the runs'
warnings. A module of its own so that ``study`` (which dispatches ``bracing-study robustness``) and
``robustness`` both import it without importing each other (test_layout: no import cycles)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bracing_analysis.ratios import ratio
from bracing_core.params import resolve_file
from bracing_experiments.experiment import STATUS_OK
from bracing_experiments.running import ARRAYS_FILE, ResultsStore, row_warnings

SCENARIO_ALIASES = {"paper": "paper_4link.yaml"}


def resolve_scenario(name: str) -> Path:
    """``paper`` or a scenario file (a path, or a name in the config directories)."""
    path = Path(name)
    if path.is_file():
        return path
    file = SCENARIO_ALIASES.get(name, name if name.endswith((".yaml", ".yml")) else f"{name}.yaml")
    return resolve_file(file, "scenario", [Path.cwd() / "config"])


def run_arrays(store: ResultsStore, run_id: str) -> dict[str, np.ndarray] | None:
    """A finished run's arrays (a RunResult's, arrays.npz), or None."""
    path = store.run_dir(run_id) / ARRAYS_FILE
    if not path.is_file():
        return None
    with np.load(path) as data:
        return {key: data[key] for key in data.files}


def is_ok(row: dict[str, Any] | None) -> bool:
    return row is not None and row.get("status") == STATUS_OK


def braced_forces(data: dict[str, np.ndarray]) -> np.ndarray:
    """f_n of the braced contacts (the columns of desired_normal_force), without the obstacle contacts'."""
    names = [str(name) for name in data["contact_names"]]
    return data["normal_force"][:, [names.index(str(name)) for name in data["braced_names"]]]


def warnings_section(rows: dict[str, dict[str, Any]]) -> list[str]:
    """The runs' warnings (summary.json's), each once with the number of runs that had it."""
    counts = row_warnings(list(rows.values()))
    if not counts:
        return []
    return [
        "## Warnings",
        "",
        *[f"- {text} ({runs} run{'s' if runs > 1 else ''})" for text, runs in counts.items()],
        "",
    ]


def ok_ratio(key: str, row: dict[str, Any] | None, baseline: dict[str, Any] | None) -> float | None:
    """``key``'s ratio of ``row`` to ``baseline`` when both runs are ok (and the ratio defined), else None."""
    if not (is_ok(row) and is_ok(baseline)):
        return None
    assert row is not None and baseline is not None
    return ratio(key, row, baseline)[0]
