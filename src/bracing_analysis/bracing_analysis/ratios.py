"""One run's metric divided by another's, or why not (no heavy imports: make run's driver uses it).

A ratio is n/a where it would mislead: a value that is missing or does not apply, energies of runs
with different input modes (voltage input books electrical joules, torque input the joints'
mechanical work: not one quantity), and a baseline value of ~0 (below ``RATIO_FLOOR``: a
torque-input force error of 5e-14 N is 0, and dividing by it gives nonsense such as 7e14).
"""

from __future__ import annotations

from typing import Any

from bracing_core.numbers import number

ENERGY_KEYS = frozenset({"energy_consumed_j", "copper_loss_j"})
"""Joules of a kind that depends on the input mode: compared only between runs of one mode."""

RATIO_FLOOR = 1e-9
"""A baseline value smaller than this (in its SI unit: m, N, J, s) is taken as 0: no ratio to it. Well
above numerical noise (a torque-input force error is ~1e-14 N, a held floor's residual ~1e-15 m) and
well below anything a run measures on purpose."""


def ratio(key: str, run: dict[str, Any], baseline: dict[str, Any]) -> tuple[float | None, str]:
    """``run[key] / baseline[key]`` of two summaries, or (None, why not)."""
    value: Any = run.get(key)
    base: Any = baseline.get(key)
    if not (number(value) and number(base)):
        return None, "n/a"
    if key in ENERGY_KEYS and run.get("input_mode") != baseline.get("input_mode"):
        return None, f"n/a ({run.get('input_mode')} vs {baseline.get('input_mode')} input)"
    if abs(base) < RATIO_FLOOR:
        return None, "n/a (baseline ~0)"
    return float(value) / float(base), ""


def ratio_text(key: str, run: dict[str, Any], baseline: dict[str, Any], digits: int = 3) -> str:
    """``ratio`` as a table cell: the ratio, or why there is none."""
    value, why = ratio(key, run, baseline)
    return f"{value:.{digits}f}" if value is not None else why


TEMPERATURE_KEY = "motor_temperature_max_c"


def temperature_saving(run: dict[str, Any], baseline: dict[str, Any]) -> float | None:
    """How many degrees cooler the hottest motor stays in ``run`` than in ``baseline`` [K] (negative:
    hotter); None without the thermal model in either (torque input, motors.thermal false). A
    difference, not a ratio: temperatures in degC have no meaningful zero."""
    value, base = run.get(TEMPERATURE_KEY), baseline.get(TEMPERATURE_KEY)
    return float(base) - float(value) if number(value) and number(base) else None


def temperature_saving_text(run: dict[str, Any], baseline: dict[str, Any]) -> str:
    """``temperature_saving`` as a table cell."""
    saved = temperature_saving(run, baseline)
    if saved is None:
        return "n/a (no thermal model)"
    return f"{saved:.3g} degC cooler" if saved >= 0 else f"{-saved:.3g} degC hotter"
