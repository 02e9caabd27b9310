"""The paper's three runs of one scenario: braced, passive, free space. One definition for every
command that makes them: ``make run`` (paper_run: bracing-pair with the flags), bracing-pair's
``--no-bracing`` / ``--free-space`` (the parameters they set), bracing-study's passive row and
bracing-optimize's reference runs (the same parameters, in process). No heavy imports."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


def variant_overrides(bracing: bool = True, free_space: bool = False) -> dict[str, Any]:
    """The shared parameters (both nodes') that bracing-pair's ``--no-bracing`` (``bracing=False``:
    no brace tasks, the surfaces kept as obstacles the arm can rest on) and ``--free-space`` (the
    surfaces removed, only watched) set."""
    out: dict[str, Any] = {}
    if not bracing:
        out["bracing"] = False
    if free_space:
        out["free_space"] = True
    return out


@dataclass(frozen=True)
class Variant:
    """One of the comparison's runs: which variant of the scenario it is (braced, passive, free space)."""

    name: str  # its directory under make run's --output
    column: str  # its column in the table
    label: str  # what it is
    bracing: bool = True
    free_space: bool = False

    def flags(self) -> str:
        """The bracing-pair options that make this run."""
        return ("" if self.bracing else " --no-bracing") + (" --free-space" if self.free_space else "")

    def overrides(self) -> dict[str, Any]:
        """The parameters those options set (what an in-process run of it overrides)."""
        return variant_overrides(self.bracing, self.free_space)


BRACED = Variant("braced", "braced", "braced")
PASSIVE = Variant("passive", "passive", "passive (no brace task, the floor an obstacle)", bracing=False)
FREE_SPACE = Variant("free_space", "free space", "free space (the paper's comparison)", bracing=False, free_space=True)
RUNS = (BRACED, PASSIVE, FREE_SPACE)
"""make run's runs, in its order."""
