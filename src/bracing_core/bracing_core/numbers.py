"""What counts as a number (a parameter's value, a metric a table shows, every entry of a node's arrays),
and numbers as table text: a cell and a Markdown table (bracing-report --compare, bracing-optimize,
bracing-study, make run's driver)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, TypeGuard

import numpy as np
from numpy.typing import ArrayLike


def all_finite(*arrays: ArrayLike) -> bool:
    """Whether every entry of every array is finite: one check of them all, as the nodes make it on every
    state (3 us for the law's six outputs, where a check per array took 8)."""
    return bool(np.isfinite(np.concatenate([np.ravel(a) for a in arrays])).all())


def number(value: Any) -> TypeGuard[float]:
    """A finite int or float (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def cell(value: Any, digits: int = 4, bools: tuple[str, str] = ("yes", "no")) -> str:
    """A table cell: n/a for a missing or non-finite number, ``bools`` for True and False, a float to
    ``digits`` significant digits, anything else as str."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if isinstance(value, bool):
        return bools[0] if value else bools[1]
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table, each value through ``cell`` (a str stays as it is)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)
