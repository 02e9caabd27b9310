"""The code speaks of the project, not of its history: no date and no issue number in the source,
its comments, docstrings and help texts (src, bench, tools, test, the Makefile, CI's script). When a
figure was measured and which issue asked for a change is CHANGELOG.md's and git's to say."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("src", "bench", "tools", "test", "Makefile", ".ci", "env.sh")
SOURCE_SUFFIXES = {".py", ".cpp", ".hpp", ".h", ".txt", ".cmake", ".sh", ".xml", ".yaml", ".yml", ".msg", ".toml"}
SKIPPED_DIRS = {"__pycache__", "data"}
"""test/data holds recorded files (their dates are data), not source."""
HISTORY = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b|\bissues? ?#?\d+", re.IGNORECASE)
"""A calendar date (YYYY-MM-DD) or an issue number ("issue N", "Issue #N", "issues N and M")."""
ALLOWED = {
    ("test/test_rcl_yaml.py", "2001-12-" + "14"): "a YAML 1.1 timestamp scalar the rcl reader must keep as a string",
}
"""(file, the text matched) -> why it stays."""


def source_files() -> list[Path]:
    files: list[Path] = []
    for name in SCANNED:
        top = ROOT / name
        if top.is_file():
            files.append(top)
            continue
        for path in sorted(top.rglob("*")):
            inside = path.relative_to(top).parts[:-1]
            if path.is_file() and path.suffix in SOURCE_SUFFIXES and not SKIPPED_DIRS.intersection(inside):
                files.append(path)
    return files


def history_in(path: Path) -> list[tuple[str, int, str]]:
    """(file, line, matched text) of each date or issue number in ``path`` that is not allowed."""
    relative = path.relative_to(ROOT).as_posix()
    found = []
    for number, line in enumerate(path.read_text(errors="replace").splitlines(), start=1):
        for match in HISTORY.finditer(line):
            if (relative, match.group()) not in ALLOWED:
                found.append((relative, number, match.group()))
    return found


def test_the_pattern_finds_dates_and_issue_numbers() -> None:
    # N for the numbers, so that this file does not hold what it looks for
    said = "measured (2026-11-N, paper arm); see issue N, Issue #N and issues N and 4".replace("N", "26")
    found = [m.group() for m in HISTORY.finditer(said)]
    assert found == "2026-11-N|issue N|Issue #N|issues N".replace("N", "26").split("|")
    clean = "depth=2000, a 1e-3 s step, 2001 states, tag:yaml.org,2002:str, the issue's arm"
    assert not HISTORY.search(clean)


def test_no_dates_or_issue_numbers_in_the_source() -> None:
    files = source_files()
    assert len(files) > 100 and ROOT / "src/bracing_engine/src/bindings.cpp" in files  # the C++ is scanned too
    found = [hit for path in files for hit in history_in(path)]
    assert not found, "history belongs in CHANGELOG.md (or add to ALLOWED, with the reason):\n" + "\n".join(
        f"{file}:{line}: {text}" for file, line, text in found
    )


def test_the_allowed_ones_are_still_there() -> None:
    """An allowance whose text has gone is stale: it would silently let the next one in."""
    for file, text in ALLOWED:
        assert text in (ROOT / file).read_text(), (file, text)
