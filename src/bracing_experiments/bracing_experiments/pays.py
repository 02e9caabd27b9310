"""bracing-study pays: when does bracing pay, by how much, and how sure is it.

    bracing-study pays --output DIR [--config FILE] [--seeds N] [--duration S] [--workers N | --scheduler ADDRESS]
                       [--forces F1,F2,...] [--positions N] [--span M] [--trials N] [--set KEY=VALUE ...]

Bracing against resting passively (bracing_core.variants.PASSIVE: no brace task, the surfaces kept as obstacles
the arm may rest on) and against free space (FREE_SPACE), over the desired normal force f_nd and the brace
place (the first braced contact's target along its first brace axis, the file's +- ``--span``; an arm whose
brace has no brace axis, such as the shipped UR5, varies f_nd only), under realistic conditions (``REALISTIC``:
the robustness study's sensing levels at once and a plant whose link masses differ from the controller's model by
a draw of the seed), each seed its own draw and noise. Then bracing-optimize searches the same axes for the
least energy at a hand error no worse than resting passively (the first seed's conditions; Optuna's TPE, its
sampler seeded), and its optimum is run again on every seed.

A cell pays on energy (on accuracy) in a seed when its braced run uses less energy (has a smaller hand RMS
error, t >= 2 s) than the passive run of the same seed; the report gives every ratio as a median with its spread
over the seeds (the range; 10-90 % with 10 seeds or more) and each conclusion with the number of cells and seeds
it holds in. Writes DIR/report.md, DIR/runs.csv (one row per run: condition, seed, f_nd, place, every metric),
DIR/tables.json (the report's tables, recorded: bracing_experiments.recorded) and the sweep's files.
Exit 0 when every run is ok, 1 when one failed, 2 on a configuration error before any run.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bracing_core import schema
from bracing_core.config import SharedConfig
from bracing_core.numbers import markdown_table, number
from bracing_core.overrides import CONTROLLER, node_params, parse_single, route
from bracing_core.params import ConfigError
from bracing_core.variants import FREE_SPACE, PASSIVE
from bracing_experiments.cli import add_study_options, check_options, study_exit
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import RunSpec
from bracing_experiments.optimize_search import Optimum, optimize
from bracing_experiments.optimize_specs import Problem, build_problem
from bracing_experiments.recorded import record_report
from bracing_experiments.reporting import is_ok, resolve_scenario
from bracing_experiments.robustness_specs import FORCE_BIAS_N, VELOCITY_FILTER_HZ
from bracing_experiments.running import ResultsStore, SweepResult, run_sweep, write_tables
from bracing_experiments.specs import make_spec
from bracing_experiments.study_cli import run_form
from bracing_experiments.study_runs import PERCENTILE_SEEDS, Median, check_window, form_scenario, seed_list
from bracing_experiments.study_specs import _brace_origin as brace_origin

STUDY = "pays"
"""bracing-study's first argument for this study (study.main dispatches it here)."""
COMMAND = f"bracing-study {STUDY}"
REPORT, RUNS, RUNS_PARQUET = "report.md", "runs.csv", "runs.parquet"
ENERGY, HAND_RMS = "energy_consumed_j", "hand_rms_error_m"
FORCE_SCALES = (0.5, 1.0, 2.0, 3.0)
"""x the file's f_nd: the grid's desired forces (the paper arm: 5, 10, 20, 30 N)."""
MASS_ERROR = 0.1
"""The plant's link masses and inertias are the model's x a scale drawn uniformly in 1 +- MASS_ERROR per seed."""
REALISTIC: dict[str, Any] = {
    "sensors.encoder_counts_per_rev": 4096,
    "sensors.velocity_filter_hz": VELOCITY_FILTER_HZ,
    "sensors.force_noise_n": 0.5,
    "sensors.force_bias_n": FORCE_BIAS_N,
    "sensors.command_latency_steps": 1,
}
"""The robustness study's realistic sensing, all at once: 4096-count encoders (dq through its low-pass), a force
sensor with 0.5 N of noise and its bias, one step of command latency."""
SEARCH_DIR, SEARCH_SEED = "optimize", 0


def conditions(seed: int) -> dict[str, Any]:
    """Seed ``seed``'s realistic conditions: its noise and its plant's mass error (drawn from the seed)."""
    scale = 1.0 + MASS_ERROR * (2.0 * np.random.default_rng(seed).random() - 1.0)
    return {**REALISTIC, "sensors.noise_seed": seed, "plant_error.mass_scale": round(float(scale), 6)}


@dataclass
class Pays:
    """Every run of the study: per seed, passive, free, the file's brace and the grid's cells."""

    config: Path
    duration: float | None
    seeds: list[int]
    contact: str
    forces: list[float]  # [N]
    places: list[float | None]  # [m] along ``axis``; [None]: the brace has no brace axis (f_nd only)
    axis: int | None
    origin: list[float]  # the contact's target as the file has it [m]
    desired: float  # the file's f_nd [N]
    base: dict[str, Any] = field(default_factory=dict)
    specs: list[RunSpec] = field(default_factory=list)

    def spec(
        self, condition: str, seed: int, force: float | None, place: float | None, extra: dict[str, Any]
    ) -> RunSpec:
        varied = {"condition": condition, "seed": seed, "f_nd": force, "place": place}
        overrides = {**conditions(seed), **self.base, **extra}  # --set over the realistic conditions
        return make_spec(self.config, varied, self.duration, overrides=overrides)

    def brace(self, force: float, place: float | None) -> dict[str, Any]:
        """The overrides that brace with ``force`` at ``place``."""
        out: dict[str, Any] = {f"contacts.{self.contact}.desired_normal_force": force}
        if place is not None and self.axis is not None:
            point = list(self.origin)
            point[self.axis] = place
            out[f"contacts.{self.contact}.target"] = point
        return out


def _contact(config: Path, base: dict[str, Any]) -> tuple[str, float, int | None, list[float]]:
    """The first braced contact: its name, f_nd, first brace axis (None: none) and target as the file has it."""
    routed = route(base)
    ctl = node_params(config, routed)[CONTROLLER]
    shared = SharedConfig.from_values(schema.read("controller", ctl), [config.resolve().parent])
    braced = [c for c in shared.contacts if c.desired_normal_force]
    if not braced:
        raise ConfigError("contacts.names: the study needs a braced contact (one with a desired_normal_force)")
    contact = braced[0]
    assert contact.desired_normal_force is not None
    if not contact.brace_axes:
        return contact.name, float(contact.desired_normal_force), None, []
    origin = brace_origin(config, routed, shared, contact)
    return contact.name, float(contact.desired_normal_force), contact.brace_axes[0], [float(v) for v in origin]


def build_pays(
    config: Path,
    seeds: int,
    duration: float | None = None,
    base: dict[str, Any] | None = None,
    forces: Sequence[float] | None = None,
    positions: int = 5,
    span: float = 0.15,
) -> Pays:
    """Every run, validated before any starts (ConfigError names the parameter)."""
    if seeds < 1:
        raise ConfigError("--seeds: at least 1")
    base = dict(base or {})
    if "sensors.noise_seed" in base:
        raise ConfigError("--set sensors.noise_seed: the study seeds every run itself (--seeds N: seeds 1..N)")
    name, desired, axis, origin = _contact(config, base)
    grid_forces = list(forces) if forces else [desired * s for s in FORCE_SCALES]
    if any(f <= 0 for f in grid_forces):
        raise ConfigError("--forces: every desired normal force must be > 0 N")
    places: list[float | None] = [None]
    if axis is not None and positions > 1:
        places = [round(origin[axis] + d, 6) for d in np.linspace(-span, span, positions)]
    elif axis is not None:
        places = [origin[axis]]
    study = Pays(config, duration, seed_list(1, seeds), name, grid_forces, places, axis, origin, desired, base)
    for seed in study.seeds:
        study.specs.append(study.spec("passive", seed, None, None, PASSIVE.overrides()))
        study.specs.append(study.spec("free", seed, None, None, FREE_SPACE.overrides()))
        file_place = origin[axis] if axis is not None else None
        study.specs.append(study.spec("file", seed, desired, file_place, {}))
        for force in grid_forces:
            for place in places:
                study.specs.append(study.spec("grid", seed, force, place, study.brace(force, place)))
    check_window(study.specs[0].duration)  # every comparison is on the hand error from t = 2 s
    return study


# -- the optimiser ---------------------------------------------------------------------------------
def search_problem(study: Pays, bound: float) -> Problem:
    """Least energy with a hand RMS no worse than ``bound`` [m] (resting passively's), over f_nd from 0 to twice
    the grid's largest and the place over the grid's span widened x 5/3, in the first seed's conditions."""
    force = f"contacts.{study.contact}.desired_normal_force"
    vary = [f"{force}=0:{2.0 * max(study.forces):g}"]
    if study.axis is not None and len(study.places) > 1:
        low, high = min(p for p in study.places if p is not None), max(p for p in study.places if p is not None)
        wide = (high - low) / 2 * (5 / 3 - 1)
        vary.append(f"contacts.{study.contact}.target[{study.axis}]={low - wide:.6g}:{high + wide:.6g}")
    base = {**conditions(study.seeds[0]), **study.base}
    return build_problem(study.config, vary, [ENERGY], [f"{HAND_RMS}<={bound:.6g}"], study.duration, base=base)


def optimum_specs(study: Pays, problem: Problem, found: Optimum) -> list[RunSpec]:
    """The optimum re-run on every seed (its own conditions each)."""
    if found.best is None:
        return []
    params = dict(found.best.params)
    force = float(params[f"contacts.{study.contact}.desired_normal_force"])
    place_key = f"contacts.{study.contact}.target[{study.axis}]"
    place = float(params[place_key]) if place_key in params else None
    brace = {key: value for key, value in problem.overrides(params).items() if key.startswith("contacts.")}
    return [study.spec("optimum", seed, round(force, 6), place, brace) for seed in study.seeds]


# -- the numbers -----------------------------------------------------------------------------------
def spread_text(values: Sequence[float], digits: int = 3) -> str:
    """``0.62 (0.58-0.66)``: the median and its spread over the seeds (study_runs.Median); n/a for none."""
    return f"{Median(values):.{digits}g}" if values else "n/a"


Rows = dict[tuple[str, int, Any, Any], dict[str, Any]]
_AfterGrid = tuple[Optimum | None, str, list[RunSpec], SweepResult | None]
"""What runs after the grid: the optimum found, the search's note, the optimum's runs and their sweep."""
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


def run_search(
    study: Pays, output: Path, executor: Any, trials: int, progress: bool
) -> tuple[Problem | None, Optimum | None, str]:
    """The optimiser's search (after the grid: its bound is the first seed's passive hand RMS)."""
    passive = ResultsStore(output).row(study.specs[0].run_id)
    if trials == 0:
        return None, None, "Not run (--trials 0)."
    if passive is None or not is_ok(passive) or not number(passive.get(HAND_RMS)):
        return None, None, "Not run: the first seed's passive run has no hand RMS error (a run of >= 2 s needed)."
    bound = float(passive[HAND_RMS])
    problem = search_problem(study, bound)
    found = optimize(
        problem, output / SEARCH_DIR / problem.key, executor, trials, progress, SEARCH_SEED, references=False
    )
    varied = ", ".join(v.flag for v in problem.varies)
    note = (
        f"bracing-optimize (Optuna's TPE, sampler seed {SEARCH_SEED}, {found.trials} trials, in seed "
        f"{study.seeds[0]}'s conditions): least `{ENERGY}` subject to `{HAND_RMS}` <= {bound * 1e3:.4g} mm (the "
        f"passive run's of that seed), over {varied}; its study: `{SEARCH_DIR}/{problem.key}/`. "
    )
    note += "Its optimum is run again in every seed (the `optimum` rows)." if found.best else "No feasible trial."
    return problem, found, note


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"bracing-study {STUDY}", description=(__doc__ or "").split("\n\n")[0])
    add_study_options(parser, exclusive_executors=True)
    parser.add_argument(
        "--forces", default="", help="f_nd of the grid [N], comma-separated (default x 0.5, 1, 2, 3 the file's)"
    )
    parser.add_argument("--positions", type=int, default=5, help="brace places in the grid (an arm with a brace axis)")
    parser.add_argument("--span", type=float, default=0.15, help="brace places: the file's +- span [m]")
    parser.add_argument("--trials", type=int, default=30, help="the optimiser's trials (default 30; 0: no search)")
    args = parser.parse_args(argv)
    check_options(parser, args)
    if args.trials < 0 or args.positions < 1 or args.span < 0:
        parser.error("--positions must be >= 1, --trials and --span >= 0")
    try:
        args.force_list = [float(f) for f in args.forces.split(",")] if args.forces else []
    except ValueError:
        parser.error(f"--forces: numbers separated by commas, not {args.forces!r}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    ran = run_form(COMMAND, args, lambda: _checked_study(args), lambda study, executor: _search(study, args, executor))
    if isinstance(ran, int):
        return ran
    found, note, again, rerun = ran.after
    specs = [*ran.study.specs, *again]
    report = write_report(ran.study, specs, args.output, found, note)
    write_runs(specs, ResultsStore(args.output), args.output)
    record_report(report, STUDY, ran.config)
    print(f"{COMMAND}: {ran.sweep.ran} run now, {ran.sweep.skipped} reused; report: {report}")
    rows = [*ran.sweep.rows, *(rerun.rows if rerun else [])]
    return study_exit(COMMAND, rows, [*ran.sweep.lost, *(rerun.lost if rerun else [])], args.output)


def _checked_study(args: argparse.Namespace) -> tuple[Path, Pays]:
    """The scenario file and the study's runs, every one checked, and the directory's manifest."""
    config = resolve_scenario(form_scenario(args.config))
    study = build_pays(
        config, args.seeds, args.duration, parse_single(args.sets), args.force_list, args.positions, args.span
    )
    ResultsStore(args.output).check_manifest(config)
    return config, study


def _search(study: Pays, args: argparse.Namespace, executor: Executor) -> _AfterGrid:
    """After the grid: the optimiser's search, then its optimum run again in every seed."""
    progress = not args.no_progress
    problem, found, note = run_search(study, args.output, executor, args.trials, progress)
    again = optimum_specs(study, problem, found) if problem is not None and found is not None else []
    rerun = run_sweep(again, args.output, executor, progress=progress) if again else None
    return found, note, again, rerun
