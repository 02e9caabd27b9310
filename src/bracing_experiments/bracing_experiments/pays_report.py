"""bracing-study pays's report: per cell of the grid, bracing's energy and hand error against passive and free
space over the seeds, where it pays, the optimum beside the file's setting; runs.csv."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bracing_core.numbers import markdown_table, number
from bracing_experiments.experiment import RunSpec
from bracing_experiments.optimize_search import Optimum
from bracing_experiments.pays_specs import ENERGY, HAND_RMS, MASS_ERROR, REALISTIC, REPORT, RUNS, RUNS_PARQUET, Pays
from bracing_experiments.reporting import is_ok
from bracing_experiments.running import ResultsStore, write_tables
from bracing_experiments.study_runs import PERCENTILE_SEEDS, Median


def spread_text(values: Sequence[float], digits: int = 3) -> str:
    """``0.62 (0.58-0.66)``: the median and its spread over the seeds (study_runs.Median); n/a for none."""
    return f"{Median(values):.{digits}g}" if values else "n/a"


Rows = dict[tuple[str, int, Any, Any], dict[str, Any]]
"""(condition, seed, f_nd, place) -> that run's row (ok runs only)."""


def rows_by_case(specs: Sequence[RunSpec], store: ResultsStore) -> Rows:
    out: Rows = {}
    for spec in specs:
        row = store.row(spec.run_id)
        if row is not None and is_ok(row):
            v = spec.varied
            out[(v["condition"], v["seed"], v["f_nd"], v["place"])] = row
    return out


def ratios(rows: Rows, seeds: Sequence[int], case: tuple[str, Any, Any], key: str, against: str) -> list[float]:
    """braced / ``against`` (passive or free) of ``key`` in every seed where both runs have it."""
    out = []
    for seed in seeds:
        braced = rows.get((case[0], seed, case[1], case[2]), {}).get(key)
        other = rows.get((against, seed, None, None), {}).get(key)
        if number(braced) and number(other) and float(other) > 0:
            out.append(float(braced) / float(other))
    return out


# -- the report ------------------------------------------------------------------------------------
@dataclass
class Cell:
    """One braced case against resting passively, over the seeds."""

    condition: str  # file | grid | optimum
    force: Any
    place: Any
    energy: list[float]  # braced / passive, one per seed
    hand: list[float]
    energy_free: list[float]  # braced / free
    hand_free: list[float]

    @property
    def pays_energy(self) -> int:
        return sum(1 for r in self.energy if r < 1.0)

    @property
    def pays_hand(self) -> int:
        return sum(1 for r in self.hand if r < 1.0)

    @property
    def pays_both(self) -> int:
        return sum(1 for e, h in zip(self.energy, self.hand, strict=True) if e < 1.0 and h < 1.0)


def cells(study: Pays, rows: Rows, condition: str, cases: Sequence[tuple[Any, Any]]) -> list[Cell]:
    out = []
    for force, place in cases:
        case = (condition, force, place)
        energy, hand = (
            ratios(rows, study.seeds, case, ENERGY, "passive"),
            ratios(rows, study.seeds, case, HAND_RMS, "passive"),
        )
        if len(energy) != len(hand):  # a seed with one of them missing: the pair is not comparable
            hand = energy = []
        free = (ratios(rows, study.seeds, case, ENERGY, "free"), ratios(rows, study.seeds, case, HAND_RMS, "free"))
        out.append(Cell(condition, force, place, energy, hand, *free))
    return out


def _seeds_text(k: int, n: int) -> str:
    return f"{k}/{n}"


def _place(value: Any) -> str:
    return "the file's (no brace axis)" if value is None else f"{float(value):.4g}"


def cell_table(items: Sequence[Cell], seeds: int) -> str:
    header = [
        "brace",
        "f_nd [N]",
        "place [m]",
        "seeds ok",
        "energy braced / passive",
        "hand RMS braced / passive",
        f"pays on energy (of {seeds} seeds)",
        "on accuracy",
        "on both",
        "energy braced / free",
        "hand RMS braced / free",
    ]
    rows = [
        [
            c.condition,
            f"{float(c.force):.4g}",
            _place(c.place),
            _seeds_text(len(c.energy), seeds),
            spread_text(c.energy),
            spread_text(c.hand),
            _seeds_text(c.pays_energy, seeds),
            _seeds_text(c.pays_hand, seeds),
            _seeds_text(c.pays_both, seeds),
            spread_text(c.energy_free),
            spread_text(c.hand_free),
        ]
        for c in items
    ]
    return markdown_table(header, rows)


def baseline_table(study: Pays, rows: Rows, optimum: Sequence[tuple[Any, Any]]) -> str:
    """Every variant's energy and hand RMS over the seeds (median and spread)."""
    cases = [("passive", None, None), ("free", None, None), ("file", study.desired, _file_place(study))]
    cases += [("optimum", force, place) for force, place in optimum]
    table = []
    for condition, force, place in cases:
        found = [rows[key] for seed in study.seeds if (key := (condition, seed, force, place)) in rows]
        energy = [float(r[ENERGY]) for r in found if number(r.get(ENERGY))]
        hand = [float(r[HAND_RMS]) * 1e3 for r in found if number(r.get(HAND_RMS))]
        what = condition if force is None else f"{condition}: f_nd {float(force):.4g} N, place {_place(place)}"
        table.append([what, f"{len(found)}/{len(study.seeds)}", spread_text(energy, 4), spread_text(hand)])
    return markdown_table(["run", "seeds ok", "energy [J]", "hand RMS [mm]"], table)


def _file_place(study: Pays) -> float | None:
    return study.origin[study.axis] if study.axis is not None else None


def region_text(items: Sequence[Cell], seeds: int, what: str, key: str) -> str:
    """Where the grid's cells pay on ``what`` in every seed: how many, and at which f_nd which places."""
    every = [c for c in items if c.energy and getattr(c, key) == len(c.energy) == seeds]
    if not every:
        return f"on {what} in no cell of the {len(items)} in all {seeds} seeds"
    where = []
    for force in sorted({float(c.force) for c in every}):
        places = sorted(float(c.place) for c in every if float(c.force) == force and c.place is not None)
        where.append(f"{force:.4g} N" + (f" at {', '.join(f'{p:.4g}' for p in places)} m" if places else ""))
    return f"on {what} in {len(every)} of {len(items)} cells in all {seeds} seeds ({'; '.join(where)})"


def answer(study: Pays, grid: Sequence[Cell], best: Sequence[Cell], file: Cell | None) -> str:
    """The report's answer (one paragraph), each claim with its cells and seeds."""
    n = len(study.seeds)
    lines = [
        "**When bracing pays** (against resting passively, in the same seed's conditions): "
        + "; ".join(
            region_text(grid, n, what, key)
            for what, key in (("energy", "pays_energy"), ("accuracy", "pays_hand"), ("both", "pays_both"))
        )
        + "."
    ]
    if file is not None and file.energy:
        lines.append(
            f"At the file's setting (f_nd {study.desired:g} N) bracing uses {spread_text(file.energy)} x the passive "
            f"energy at {spread_text(file.hand)} x its hand RMS error (over {len(file.energy)} seeds); "
            f"it pays on energy in {file.pays_energy} and on both in {file.pays_both} of them."
        )
    for cell in best:
        if cell.energy:
            lines.append(
                f"The optimiser's brace (f_nd {float(cell.force):.4g} N, place {_place(cell.place)}) uses "
                f"{spread_text(cell.energy)} x the passive energy at {spread_text(cell.hand)} x its hand RMS error, "
                f"{spread_text(cell.energy_free)} x free space's energy: it pays on both in {cell.pays_both} of "
                f"{len(cell.energy)} seeds."
            )
    return " ".join(lines)


def write_runs(specs: Sequence[RunSpec], store: ResultsStore, output: Path) -> None:
    """DIR/runs.csv and DIR/runs.parquet: one row per run (condition, seed, f_nd, place, then every metric)."""
    rows = [row for spec in specs if (row := store.row(spec.run_id)) is not None]
    write_tables(output, rows, ["condition", "seed", "f_nd", "place"], RUNS_PARQUET, RUNS)


def write_report(study: Pays, specs: Sequence[RunSpec], output: Path, found: Optimum | None, note: str) -> Path:
    store = ResultsStore(output)
    rows = rows_by_case(specs, store)
    grid = cells(study, rows, "grid", [(f, p) for f in study.forces for p in study.places])
    file = cells(study, rows, "file", [(study.desired, _file_place(study))])[0]
    best_cases = sorted({(s.varied["f_nd"], s.varied["place"]) for s in specs if s.varied["condition"] == "optimum"})
    best = cells(study, rows, "optimum", best_cases)
    n, ok = len(study.seeds), sum(1 for s in specs if is_ok(store.row(s.run_id)))
    realistic = ", ".join(f"`{k}` {v}" for k, v in REALISTIC.items())
    lines = [
        f"# When bracing pays: {study.config.name}",
        "",
        f"{len(specs)} in-process runs ({ok} ok) of {specs[0].duration:g} s, {n} seed{'s' if n > 1 else ''} "
        f"({', '.join(map(str, study.seeds))}). Every run under realistic conditions: {realistic}; "
        f"`sensors.noise_seed` the seed and `plant_error.mass_scale` drawn in 1 +- {MASS_ERROR:g} from it "
        "(`runs.csv`: every run's row). Hand errors over t >= 2 s. A median is followed by its spread over the "
        f"seeds (the range; 10-90 % from {PERCENTILE_SEEDS} seeds). *Passive*: no brace task, the surfaces kept as "
        "obstacles the arm may rest on; *free*: no contact; *file*: the brace as the file sets it.",
        "",
        answer(study, grid, best, file),
        "",
        "## The runs beside each other",
        "",
        baseline_table(study, rows, best_cases),
        "",
        "## Braced against passive and free, per force and place",
        "",
        "A ratio below 1 means bracing uses less energy (a smaller hand error) than the other run of the same seed; "
        "a seed whose braced or passive run failed (its error: `runs.csv`) has no ratio and does not pay.",
        "",
        cell_table([file, *grid, *best], n),
        "",
        "## The optimiser",
        "",
        note,
        "",
    ]
    path = output / REPORT
    path.write_text("\n".join(lines))
    return path
