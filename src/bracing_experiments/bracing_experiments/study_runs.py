"""What every bracing-study form shares: its scenario (``--config``), its seeds (``--seeds``), the window of
the windowed metrics checked against the runs' duration, DIR/runs.csv (one row per condition and seed) and
the figures over seeds (a median printed with its spread) and the conclusions' counts (in how many
conditions and seeds a statement holds).

A form builds each condition's runs through ``Replicas.add`` with a function of the seed. A run whose
parameters draw noise (``NOISE_KEYS``) gets ``sensors.noise_seed`` = the seed, one run per seed; a run that
draws nothing random is one run shared by every seed (its parameters, hence its run id, are the same: the
sweep runs it once), and runs.csv says so (``seeded`` false).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bracing_analysis.summary import HAND_ERROR_T_MIN_S, WINDOWED_KEYS
from bracing_core.params import ConfigError
from bracing_experiments.experiment import STATUS_OK, RunSpec
from bracing_experiments.running import ResultsStore, write_tables

DEFAULT_SCENARIO = "paper"
RUNS_CSV, RUNS_PARQUET = "runs.csv", "runs.parquet"
SEED_KEY = "sensors.noise_seed"
NOISE_KEYS = (
    "sensors.position_noise_rad",
    "sensors.velocity_noise_rad_s",
    "sensors.force_noise_n",
    "sensors.current_noise_a",
)
"""The simulator's parameters that draw random numbers (from sensors.noise_seed) when > 0; nothing else in a
run is random (the plant errors are scales, not draws)."""
PERCENTILE_SEEDS = 10
"""From this many seeds on, the spread is the 10-90 % range; below, the whole range (min-max)."""
BOOKKEEPING = ("worker", "traceback")
"""A run's row columns that are not its outcome (where it ran): left out of runs.csv."""


def draws_noise(sim_params: Mapping[str, Any]) -> bool:
    """Whether a run with these simulator parameters draws random numbers."""
    return any(float(sim_params.get(key) or 0.0) > 0.0 for key in NOISE_KEYS)


def seed_list(first: int, count: int) -> list[int]:
    """The seeds of a study: ``first`` and the ``count - 1`` after it."""
    return [first + k for k in range(count)]


def seed_label(extra: Mapping[str, Any]) -> dict[str, Any]:
    """A seeded run's table column (its seed), from the overrides ``Replicas.add`` gave it."""
    return {"seed": extra[SEED_KEY]} if SEED_KEY in extra else {}


def check_window(duration: float, option: str = "--duration", metrics: Sequence[str] = WINDOWED_KEYS) -> None:
    """Refuse, before any run, runs too short for the windowed ``metrics`` among WINDOWED_KEYS (their window
    starts at HAND_ERROR_T_MIN_S): each would be null, and what is judged on them empty. ConfigError says
    what to set."""
    windowed = [key for key in WINDOWED_KEYS if key in metrics]
    if windowed and duration <= HAND_ERROR_T_MIN_S:
        raise ConfigError(
            f"{option} {duration:g}: {', '.join(windowed)} count over t >= {HAND_ERROR_T_MIN_S:g} s (after the "
            f"start's transient), so runs of {duration:g} s leave them no sample; set {option} above "
            f"{HAND_ERROR_T_MIN_S:g} (the scenario's own duration, or more)"
        )


def window_text(duration: float) -> str:
    """The windowed metrics' window, as a report states it: what part of each run it covers, or that the
    runs end before it starts (their hand errors are then null and nothing is judged on them)."""
    if duration <= HAND_ERROR_T_MIN_S:
        return (
            f"Hand errors (RMS, max) count over t >= {HAND_ERROR_T_MIN_S:g} s (after the start's transient): "
            f"runs of {duration:g} s end before that window opens, so they are not measured here (null in "
            f"runs.csv) and no figure or conclusion below is about the hand; run longer than "
            f"{HAND_ERROR_T_MIN_S:g} s (--duration) to judge it."
        )
    covered = duration - HAND_ERROR_T_MIN_S
    return (
        f"Hand errors (RMS, max) count over t in [{HAND_ERROR_T_MIN_S:g}, {duration:g}] s: the last {covered:g} s "
        f"of each {duration:g} s run, the first {HAND_ERROR_T_MIN_S:g} s (the start's transient) left out."
    )


class Median(float):
    """A median over seeds that prints with its spread: ``f"{m:.4g}"`` gives "0.0123 (0.0120-0.0127)" when
    the seeds differ (the range, or 10-90 % from PERCENTILE_SEEDS seeds on), the plain number when they do
    not. As a float it is the median (ratios and comparisons use it)."""

    low: float
    high: float

    def __new__(cls, values: Sequence[float]) -> Median:
        data = np.asarray(values, dtype=float)
        median = super().__new__(cls, float(np.median(data)))
        if data.size >= PERCENTILE_SEEDS:
            median.low, median.high = (float(v) for v in np.percentile(data, [10.0, 90.0]))
        else:
            median.low, median.high = float(data.min()), float(data.max())
        return median

    def __format__(self, spec: str) -> str:
        text = float(self).__format__(spec)
        low, high = self.low.__format__(spec), self.high.__format__(spec)
        return text if low == high else f"{text} ({low}-{high})"


def spread_name(seeds: int) -> str:
    """What the parentheses after a median hold."""
    return "10-90 %" if seeds >= PERCENTILE_SEEDS else "min-max"


def median_row(rows: Sequence[dict[str, Any] | None]) -> dict[str, Any] | None:
    """One condition's rows over seeds as one row: each number a ``Median`` (the other values the first
    seed's). A failed or missing seed makes the condition's row that one (a report's cell says it)."""
    if not rows or any(row is None or row.get("status") != STATUS_OK for row in rows):
        return next((row for row in rows if row is None or row.get("status") != STATUS_OK), None)
    first = dict(rows[0])  # type: ignore[arg-type]  # (every row is a dict: checked above)
    if len(rows) == 1:
        return first
    for key, value in first.items():
        values = [row.get(key) for row in rows]  # type: ignore[union-attr]
        if isinstance(value, float) and all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            first[key] = Median(values)  # type: ignore[arg-type]
    return first


def holds_text(held: Mapping[str, Sequence[bool]], seeds: int) -> str:
    """How many conditions a statement holds in, over ``seeds`` seeds: "in 17 of 19 conditions, in 5 of 5
    seeds" (in every seed), with "; in 18 of 19 in at least 1 of 5 seeds" when that differs."""
    total = len(held)
    every = sum(1 for results in held.values() if results and all(results))
    some = sum(1 for results in held.values() if any(results))
    text = f"in {every} of {total} conditions, in {seeds} of {seeds} seed{'s' if seeds > 1 else ''}"
    return text + (f"; in {some} of {total} in at least 1 of {seeds} seeds" if some != every else "")


def condition_name(labels: Mapping[str, Any]) -> str:
    """A condition in runs.csv: its labels, ``key=value`` joined by '; ' (None left out)."""
    return "; ".join(f"{key}={value}" for key, value in labels.items() if value is not None)


@dataclass
class Replicas:
    """Every condition of a study, its run for each seed; keyed by the first seed's run id (the id a form's
    report looks its rows up by)."""

    seeds: list[int]
    runs: dict[str, list[RunSpec]] = field(default_factory=dict)  # first seed's run id -> one spec per seed
    conditions: dict[str, str] = field(default_factory=dict)  # first seed's run id -> its condition
    seeded: dict[str, bool] = field(default_factory=dict)  # ... -> the seed enters its runs (they draw noise)

    def add(self, labels: Mapping[str, Any], make: Callable[[dict[str, Any]], RunSpec]) -> RunSpec:
        """The condition ``labels`` whose run is ``make(extra overrides)``; its first seed's spec."""
        plain = make({})
        if draws_noise(plain.sim_params):
            specs = [make({SEED_KEY: seed}) for seed in self.seeds]
        else:
            specs = [plain] * len(self.seeds)
        first = specs[0].run_id
        self.runs[first] = specs
        self.conditions[first] = condition_name(labels)
        self.seeded[first] = len({spec.run_id for spec in specs}) > 1 or draws_noise(plain.sim_params)
        return specs[0]

    @property
    def specs(self) -> list[RunSpec]:
        """Every run to execute, once each."""
        unique = {spec.run_id: spec for specs in self.runs.values() for spec in specs}
        return list(unique.values())

    def seed_rows(self, store: ResultsStore, k: int) -> dict[str, dict[str, Any]]:
        """The ``k``-th seed's rows, keyed by the first seed's run ids (finished runs only)."""
        out = {}
        for first, specs in self.runs.items():
            row = store.row(specs[k].run_id)
            if row is not None:
                out[first] = row
        return out

    def median_rows(self, store: ResultsStore) -> dict[str, dict[str, Any]]:
        """Each condition's row over its seeds (``median_row``), keyed by the first seed's run id."""
        out = {}
        for first, specs in self.runs.items():
            row = median_row([store.row(spec.run_id) for spec in specs])
            if row is not None:
                out[first] = row
        return out

    def write_runs(self, store: ResultsStore) -> list[dict[str, Any]]:
        """DIR/runs.csv and DIR/runs.parquet: one row per condition and seed (condition, seed, seeded, then
        the run's row: its labels, status, error and every summary metric). A run not finished has no row."""
        rows = []
        for first, specs in self.runs.items():
            for seed, spec in zip(self.seeds, specs, strict=True):
                row = store.row(spec.run_id)
                if row is None:
                    continue
                kept = {key: value for key, value in row.items() if key not in BOOKKEEPING}
                kept.pop("seed", None)  # the label of a seeded run: the column below
                rows.append({"condition": self.conditions[first], "seed": seed, "seeded": self.seeded[first], **kept})
        write_tables(store.output, rows, ("condition", "seed", "seeded"), RUNS_PARQUET, RUNS_CSV)
        return rows

    def summary_text(self) -> str:
        """What a report says of its seeds."""
        noisy = sum(1 for seeded in self.seeded.values() if seeded)
        if len(self.seeds) == 1:
            return f"One seed ({self.seeds[0]}, `{SEED_KEY}`): each figure is one run (`--seeds N`: N per condition)."
        return (
            f"{len(self.seeds)} seeds ({self.seeds[0]}-{self.seeds[-1]}, `{SEED_KEY}`): {noisy} of "
            f"{len(self.runs)} conditions draw noise and run once per seed; the rest draw nothing random and "
            f"are one run that counts for every seed. Each figure is the median over seeds with its spread "
            f"({spread_name(len(self.seeds))}) in parentheses when the seeds differ, a ratio that of the medians; "
            f"every run: `{RUNS_CSV}`."
        )


def form_scenario(config: str | None, given: str | None = None) -> str:
    """The scenario a form runs: ``--config``, else ``given`` (a file named as bracing-study's first argument),
    else the paper's. ConfigError when both name one and they differ."""
    if config is not None and given is not None and Path(config) != Path(given):
        raise ConfigError(f"--config {config}: the scenario is also given as {given}; give it once")
    return config or given or DEFAULT_SCENARIO
