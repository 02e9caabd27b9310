"""The paper study's report (bracing-study paper): its three sections and their tables, from the runs'
rows (the optimum's section: study_optimum; the figures: study_figures)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bracing_analysis.ratios import TEMPERATURE_KEY, ratio, temperature_saving, temperature_saving_text
from bracing_analysis.summary import HAND_ERROR_T_MIN_S
from bracing_core.numbers import markdown_table
from bracing_experiments.experiment import FORCE_MAX_ERROR_KEY
from bracing_experiments.reporting import braced_forces as _braced_forces
from bracing_experiments.reporting import is_ok as _ok
from bracing_experiments.reporting import run_arrays as _arrays
from bracing_experiments.reporting import warnings_section as _warnings_section
from bracing_experiments.running import ResultsStore
from bracing_experiments.study_figures import draw_bracing, draw_gains, draw_placement
from bracing_experiments.study_optimum import _search_lines
from bracing_experiments.study_runs import holds_text, window_text
from bracing_experiments.study_specs import ENERGY, HAND_MAX, HAND_RMS, REPORT, PlacementSearch, Study


# -- the report ------------------------------------------------------------------------------------
def _columns(header: str) -> list[str]:
    """A table's columns, written as its header row reads (``a | b | c``)."""
    return header.split(" | ")


_RATIO_COLUMNS = _columns(
    "input | gravity comp. | energy braced / free | hand RMS braced / free | energy braced / passive | "
    "hand RMS braced / passive | hottest motor, braced"
)
_Lookup = dict[tuple[Any, str, bool], dict[str, Any] | None]
"""(bracing: True | False | "passive", input mode, gravity compensation) -> that run's row."""


def _bracing_table(study: Study, rows: dict[str, dict[str, Any]]) -> tuple[list[list[Any]], _Lookup]:
    """Comparison 1's table (braced, passive, free) and its rows by case."""
    keys = (HAND_RMS, HAND_MAX, ENERGY, "copper_loss_j", TEMPERATURE_KEY)
    table: list[list[Any]] = []
    lookup: _Lookup = {}
    cases = [(spec, spec.varied["bracing"]) for spec in study.bracing if spec.varied["bracing"]]
    cases += [(spec, "passive") for spec in study.passive]
    cases += [(spec, spec.varied["bracing"]) for spec in study.bracing if not spec.varied["bracing"]]
    for spec, kind in cases:
        row = rows.get(spec.run_id)
        v = spec.varied
        lookup[(kind, v["input_mode"], v["gravity_compensation"])] = row
        labels = [kind, v["input_mode"], v["gravity_compensation"]]
        if row is not None and _ok(row):
            table.append([*labels, *(row.get(k) for k in keys)])
        else:
            table.append([*labels, f"failed: {row.get('error') if row else 'not run'}", "", "", "", ""])
    return table, lookup


def _bracing_findings(
    case: str,
    energy: float | None,
    hand: float | None,
    resting: list[float | None],
    passive: dict[str, Any] | None,
    saved: float | None,
) -> list[str]:
    """What one case's ratios say, a sentence each."""
    findings = []
    if hand is not None and energy is not None:
        better = "more precise" if hand < 1 else "less precise"
        findings.append(
            f"{case}: bracing uses {energy:.3g} x the energy and the hand is {better} (RMS error x {hand:.3g})."
        )
    if passive is not None and resting[0] is not None and resting[1] is not None:
        findings.append(
            f"{case}: bracing uses {resting[0]:.3g} x the energy of resting passively, its hand RMS error "
            f"x {resting[1]:.3g} of the passive one's."
        )
    if saved is not None:
        findings.append(
            f"{case}: bracing keeps the hottest motor {abs(saved):.3g} degC "
            f"{'cooler' if saved >= 0 else 'hotter'} than free."
        )
    return findings


def _bracing_ratios(lookup: _Lookup) -> tuple[list[list[Any]], list[str]]:
    """Braced against free and against passive, per input and compensation: the ratios' table, the findings."""
    ratios = []
    findings = []
    for mode in ("voltage", "torque"):
        for compensation in (False, True):
            braced, free = lookup.get((True, mode, compensation)), lookup.get((False, mode, compensation))
            passive = lookup.get(("passive", mode, compensation))
            case = f"{mode} input, {'with' if compensation else 'without'} gravity compensation"
            if not (_ok(braced) and _ok(free)):
                continue
            assert braced is not None and free is not None
            energy = ratio(ENERGY, braced, free)[0]
            hand = ratio(HAND_RMS, braced, free)[0]
            resting = [ratio(k, braced, passive)[0] if passive and _ok(passive) else None for k in (ENERGY, HAND_RMS)]
            ratios.append([mode, compensation, energy, hand, *resting, temperature_saving_text(braced, free)])
            findings += _bracing_findings(case, energy, hand, resting, passive, temperature_saving(braced, free))
    return ratios, findings


def _bracing_section(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> list[str]:
    header = _columns(
        "bracing | input | gravity comp. | hand RMS [m] | hand max [m] | energy [J] | copper loss [J] | "
        "hottest motor [degC]"
    )
    table, lookup = _bracing_table(study, rows)
    ratios, findings = _bracing_ratios(lookup)
    lines = [
        "## 1. Braced, passive and free",
        "",
        "The same hand task with the contact braced, resting passively (`passive`, make run's: no brace task,",
        "the surfaces kept as obstacles the arm may rest on) and without any contact (free), for both input",
        "modes, with and without gravity compensation in the null space. Hand errors over "
        f"t >= {HAND_ERROR_T_MIN_S:g} s.",
        "",
        markdown_table(header, table),
        "",
        markdown_table(_RATIO_COLUMNS, ratios),
        "",
        *[f"- {line}" for line in findings],
        *_bracing_over_seeds(study, store),
        "",
        "![hand error and energy over time, braced, passive and free](bracing.png)",
        "",
    ]
    draw_bracing(study, store, rows)
    return lines


def _bracing_over_seeds(study: Study, store: ResultsStore) -> list[str]:
    """With several seeds: in how many of comparison 1's cases (input, compensation) bracing uses less energy
    and keeps the hand more precise than free and than passive, in all seeds (``study_runs.holds_text``)."""
    seeds = study.replicas.seeds
    if len(seeds) < 2:
        return []
    held: dict[str, dict[str, list[bool]]] = {}  # statement -> case -> whether it holds, seed by seed
    for k in range(len(seeds)):
        _, lookup = _bracing_table(study, study.replicas.seed_rows(store, k))
        for mode in ("voltage", "torque"):
            for compensation in (False, True):
                braced = lookup.get((True, mode, compensation))
                baselines = (
                    ("free", (False, mode, compensation)),
                    ("resting passively", ("passive", mode, compensation)),
                )
                for name, key in baselines:
                    baseline = lookup.get(key)
                    if not (_ok(braced) and _ok(baseline)):
                        continue
                    assert braced is not None and baseline is not None
                    for metric, what in ((ENERGY, "uses less energy"), (HAND_RMS, "keeps the hand more precise")):
                        value = ratio(metric, braced, baseline)[0]
                        if value is not None:
                            cases = held.setdefault(f"bracing {what} than {name}", {})
                            cases.setdefault(f"{mode}, {compensation}", []).append(value < 1)
    return [f"- Seed by seed, {statement} {holds_text(cases, len(seeds))}." for statement, cases in held.items()]


def _gains_section(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> list[str]:
    header = _columns(
        "input | gain scale | force max err [N] | force RMS err [N] | hand RMS [m] | hand max [m] | brace RMS [m]"
    )
    table = []
    worst: dict[str, float] = {}
    for spec in study.gains:
        row = rows.get(spec.run_id)
        v = spec.varied
        if not _ok(row):
            table.append([v["input_mode"], v["gain_scale"], f"failed: {row.get('error') if row else 'not run'}"])
            continue
        assert row is not None
        keys = (
            FORCE_MAX_ERROR_KEY,
            "normal_force_rms_error_n",
            "hand_rms_error_m",
            "hand_max_error_m",
            "brace_rms_error_m",
        )
        table.append([v["input_mode"], v["gain_scale"], *(row.get(k) for k in keys)])
        force = row.get(FORCE_MAX_ERROR_KEY)
        if isinstance(force, (int, float)):
            worst[v["input_mode"]] = max(worst.get(v["input_mode"], 0.0), float(force))
    findings = []
    if "torque" in worst:
        findings.append(
            f"Torque input: the largest force error over every gain scale is {worst['torque']:.2g} N "
            "(machine precision: f_n = f_nd every step, eq. 40), while the position errors grow as the gains drop."
        )
    if "voltage" in worst:
        early, late = _voltage_force_errors(study, store, rows)
        findings.append(
            f"Voltage input: the force error reaches {early:.3g} N in the initial transient (t < "
            f"{HAND_ERROR_T_MIN_S:g} s) and at most {late:.3g} N after it: the law sets voltages, and the "
            "motor currents (hence torques) lag them through L and the back-EMF; the position errors grow as with "
            "torque input."
        )
    lines = [
        "## 2. Gains: position and force are decoupled",
        "",
        "All PD gains (hand and brace, Kp and Kd) scaled together, braced"
        + study.paper(", paper Sec. 4 / Figs. 9-16")
        + ".",
        "",
        markdown_table(header, table),
        "",
        *[f"- {line}" for line in findings],
        "",
        "![force error against position errors as the gains drop](gains.png)",
        "",
    ]
    draw_gains(study, store, rows)
    return lines


def _voltage_force_errors(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> tuple[float, float]:
    """max |f_n - f_nd| [N] over the voltage-input gain runs: in the transient (t < 2 s) and after."""
    early, late = 0.0, 0.0
    for spec in study.gains:
        if spec.varied["input_mode"] != "voltage" or not _ok(rows.get(spec.run_id)):
            continue
        data = _arrays(store, spec.run_id)
        if data is None or not data["desired_normal_force"].size:
            continue
        error = np.max(np.abs(_braced_forces(data) - data["desired_normal_force"]), axis=1)
        after = data["time"] >= HAND_ERROR_T_MIN_S - 1e-9
        early = max(early, float(np.max(error[~after], initial=0.0)))
        late = max(late, float(np.max(error[after], initial=0.0)))
    return early, late


def _placement_section(
    study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]], search: PlacementSearch | None, note: str
) -> list[str]:
    grids = {key: np.full((len(study.forces), len(study.targets)), np.nan) for key in (ENERGY, HAND_RMS, HAND_MAX)}
    failed = []
    for k, spec in enumerate(study.placement):
        i, j = divmod(k, len(study.targets))
        row = rows.get(spec.run_id)
        if not _ok(row):
            failed.append(
                f"target {study.targets[j]:.3f} m, f_nd {study.forces[i]:g} N: {row.get('error') if row else 'not run'}"
            )
            continue
        assert row is not None
        for key, grid in grids.items():
            value = row.get(key)
            grid[i, j] = value if isinstance(value, (int, float)) else np.nan
    lines = [
        "## 3. Where and how hard to brace",
        "",
        f"Contact `{study.contact}`: brace target along {study.axis} (its start position +- the span) and desired",
        "normal force; the rest as in the scenario. Best cell (least) marked.",
        "",
    ]
    header = ["f_nd [N] \\ target " + study.axis + " [m]", *[f"{t:.3f}" for t in study.targets]]
    for key, title in ((ENERGY, "energy consumed [J]"), (HAND_RMS, "hand RMS error [m]")):
        grid = grids[key]
        lines += [f"**{title}**", "", markdown_table(header, [[f, *grid[i]] for i, f in enumerate(study.forces)]), ""]
        if np.isfinite(grid).any():
            i, j = (int(x) for x in np.unravel_index(np.nanargmin(grid), grid.shape))
            lines += [
                f"- least {title.split(' [')[0]}: {grid[i, j]:.4g} at target {study.axis} = "
                f"{study.targets[j]:.3f} m, f_nd = {study.forces[i]:g} N",
                "",
            ]
    lines += [f"- failed: {f}" for f in failed]
    optimum = search.optimum if search is not None else None
    lines += ["", *_search_lines(study, rows, search, note)]
    lines += ["![energy and hand error over brace target and force](placement.png)", ""]
    point = None
    if search is not None and optimum is not None and search.found is not None and search.found.best is not None:
        params = search.found.best.params
        point = (params[search.target] if search.target else study.origin, params[search.force])
    draw_placement(study, store, grids, point)
    return lines


def write_report(
    study: Study,
    output: Path,
    wall_time_s: float,
    executor: str,
    reused: int = 0,
    search: PlacementSearch | None = None,
    search_note: str = "",
) -> Path:
    """DIR/report.md and its figures from the runs in DIR (and the optimiser's ``search``, when it ran;
    ``search_note``: why it did not)."""
    import matplotlib  # imported where used: matplotlib ~460 ms (python -X importtime)

    matplotlib.use("Agg")
    store = ResultsStore(output)
    rows = study.replicas.median_rows(store)
    ok = sum(1 for row in rows.values() if _ok(row))
    duration = study.duration if study.duration is not None else study.specs[0].duration
    compute = sum(float(row.get("wall_time_s") or 0.0) for row in rows.values())
    lines = [
        f"# Bracing study: {study.config.name}",
        "",
        f"{len(study.specs)} in-process runs of {duration:g} s (the nodes' simulator and controller cores, "
        f"lockstep), {len(study.replicas.runs)} conditions: {ok} ok, {len(rows) - ok} failed. "
        f"{compute:.0f} s of run time in all; this report's "
        f"invocation took {wall_time_s:.0f} s on {executor}{f' ({reused} runs reused)' if reused else ''}"
        f"{_search_count(search)}. "
        "Every run's row: `results.csv` / `results.parquet`; its summary and arrays: `runs/<run id>/`.",
        "",
        f"{window_text(duration)} {study.replicas.summary_text()}"
        + (" The figures over time show the first seed's runs." if len(study.replicas.seeds) > 1 else ""),
        "",
        *_bracing_section(study, store, rows),
        *_gains_section(study, store, rows),
        *_placement_section(study, store, rows, search, search_note),
        *_warnings_section(rows),
    ]
    path = output / REPORT
    path.write_text("\n".join(lines))
    study.replicas.write_runs(store)
    return path


def _search_count(search: PlacementSearch | None) -> str:
    if search is None or search.found is None:
        return ""
    return f", the optimiser's {search.found.trials} trials included ({search.found.search.ran} run now)"
