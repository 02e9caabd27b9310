"""Recorded result files: what a study or ``make bench`` measured, with when, from which commit and on which
machine, so that the docs' results pages are rendered from them (tools/docs_reference.py) instead of typed.

A recorded file is JSON with a ``recorded`` entry (``date``, ``time_utc``, ``commit``, ``dirty``, ``machine``)
beside what was measured: ``make bench`` keeps bench/latest.json's keys; a study keeps its report's tables,
each as its header and its rows of cells exactly as the report prints them (``tables``: {key: {"header",
"rows"}}), so a table rendered from the file is the report's byte for byte (``markdown_table``), and the
report's generated conclusions (``conclusions``: {key: the paragraph}).
"""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import time
from importlib import metadata
from pathlib import Path
from typing import Any

from bracing_core.numbers import markdown_table

RECORDED_KEY = "recorded"
TABLES_FILE = "tables.json"
"""A study's recorded file beside its report.md (copy it to docs/results/data/ to publish it)."""
CODE_PATHS = ("src", "config", "bench", "tools")
"""What makes the numbers: a change under these (tracked files) marks a recording ``dirty``; docs do not."""
VERSIONED = ("numpy", "pin", "mujoco", "ros-jazzy-rclpy", "rosbags", "optuna")
"""The distributions whose versions a recorded file names (the numbers depend on them)."""


def machine() -> dict[str, Any]:
    """The machine and the versions the numbers were measured with."""
    versions: dict[str, str | None] = {}
    for dist in VERSIONED:
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return {
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "versions": versions,
        "date": time.strftime("%Y-%m-%d", time.gmtime()),
    }


def _git(repo: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def provenance(repo: Path | None = None) -> dict[str, Any]:
    """When (UTC), from which commit of ``repo`` (default the working directory; null outside a git
    checkout; ``dirty``: tracked files under CODE_PATHS changed since it) and on which machine."""
    where = Path.cwd() if repo is None else repo
    commit = _git(where, "rev-parse", "--short=7", "HEAD")
    top = _git(where, "rev-parse", "--show-toplevel") if commit else None
    paths = [str(Path(top) / path) for path in CODE_PATHS] if top else []
    changes = _git(where, "status", "--porcelain", "--untracked-files=no", "--", *paths) if top else None
    now = time.gmtime()
    return {
        "date": time.strftime("%Y-%m-%d", now),
        "time_utc": time.strftime("%H:%M:%S", now),
        "commit": commit,
        "dirty": bool(changes) if commit else None,
        "machine": machine(),
    }


def write_recorded(path: Path, content: dict[str, Any], repo: Path | None = None) -> Path:
    """``content`` with its provenance, as JSON (keys in the order given, the provenance first)."""
    path.write_text(json.dumps({RECORDED_KEY: provenance(repo), **content}, indent=2) + "\n")
    return path


def _slug(heading: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", heading.lower()).strip("-")


def _cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().removeprefix("|").removesuffix("|").split(" | ")]


def report_tables(markdown: str) -> dict[str, dict[str, list[Any]]]:
    """Every table of a report: {key: {"header": [...], "rows": [[...], ...]}}, the key the slug of the
    heading (or bold lead, ``**1. Braced ...**``) above it, ``-2``, ``-3`` for a second and third under it."""
    tables: dict[str, dict[str, list[Any]]] = {}
    heading, lines = "report", markdown.splitlines()
    k = 0
    while k < len(lines):
        line = lines[k]
        if line.startswith("#") or (lead := re.match(r"\*\*([^*]+)\*\*", line)):
            heading = _slug(line.lstrip("#") if line.startswith("#") else lead.group(1))  # type: ignore[union-attr]
        if line.startswith("|") and k + 1 < len(lines) and re.fullmatch(r"\|(---\|)+", lines[k + 1]):
            body = []
            k += 2
            while k < len(lines) and lines[k].startswith("|"):
                body.append(_cells(lines[k]))
                k += 1
            key, n = heading, 2
            while key in tables:
                key, n = f"{heading}-{n}", n + 1
            tables[key] = {"header": _cells(line), "rows": body}
            continue
        k += 1
    return tables


def report_conclusions(markdown: str) -> dict[str, str]:
    """Every paragraph of a report that opens with a bold lead (``**When bracing pays** ...``, one line), by the
    lead's slug: a conclusion the report generated from its tables."""
    out: dict[str, str] = {}
    for line in markdown.splitlines():
        if lead := re.match(r"\*\*([^*]+)\*\*", line):
            out.setdefault(_slug(lead.group(1)), line)
    return out


def record_report(report: Path, study: str, config: Path, repo: Path | None = None) -> Path:
    """``report``'s tables and conclusions as a recorded file beside it (DIR/tables.json: the study, its scenario
    file, the tables, the conclusions), each table rendered back by ``render_table`` byte for byte."""
    text = report.read_text()
    content = {"study": study, "config": config.name, "tables": report_tables(text)}
    content["conclusions"] = report_conclusions(text)
    return write_recorded(report.parent / TABLES_FILE, content, repo)


def render_table(table: dict[str, list[Any]]) -> str:
    """A recorded table as its report printed it."""
    return markdown_table(table["header"], table["rows"])


def provenance_line(recorded: dict[str, Any]) -> str:
    """``recorded YYYY-MM-DD, commit abc1234, 2-core x86_64 (Python 3.11.7, pin 4.1.0, ...)``."""
    box = recorded["machine"]
    versions = ", ".join(f"{name} {version}" for name, version in box["versions"].items() if version)
    commit = recorded.get("commit") or "unknown"
    dirty = " with uncommitted changes" if recorded.get("dirty") else ""
    return (
        f"recorded {recorded['date']}, commit {commit}{dirty}, {box['cores']}-core {box['processor']} "
        f"(Python {box['python']}, {versions})"
    )
