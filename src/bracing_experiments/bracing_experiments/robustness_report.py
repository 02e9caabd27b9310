"""The robustness study's report (bracing-study robustness): its tables and the paragraph that answers
where bracing still pays and what force feedback buys, from the runs' rows (its figures:
robustness_figures)."""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bracing_analysis.ratios import RATIO_FLOOR
from bracing_analysis.summary import HAND_ERROR_T_MIN_S
from bracing_core.numbers import markdown_table, number
from bracing_core.variants import Variant
from bracing_experiments.reporting import braced_forces, is_ok, ok_ratio, run_arrays, warnings_section
from bracing_experiments.robustness_figures import draw_factor
from bracing_experiments.robustness_specs import (
    BRACED,
    ENERGY,
    FEEDBACK_LAW,
    FORCE_LATE,
    FORCE_RMS,
    FREE_SPACE,
    HAND_RMS,
    LAW_TEXT,
    LAWS,
    NOMINAL_LEVEL,
    PAPER_LAW,
    PASSIVE,
    REPORT,
    TORQUE,
    VARIANTS,
    Factor,
    Level,
    Robustness,
    _gains,
    force_error,
)
from bracing_experiments.running import ResultsStore
from bracing_experiments.study_runs import holds_text, median_row, window_text

if TYPE_CHECKING:
    pass


# -- the numbers --------------------------------------------------------------------------------------
def late_force_rms(store: ResultsStore, row: dict[str, Any] | None) -> float | None:
    """|f_n - f_nd| RMS [N] over t >= HAND_ERROR_T_MIN_S of a braced run's braced contacts (None: no such
    run, no samples that late, no braced contact)."""
    if not is_ok(row):
        return None
    assert row is not None
    data = run_arrays(store, str(row["run_id"]))
    if data is None or not data["desired_normal_force"].size:
        return None
    late = data["time"] >= HAND_ERROR_T_MIN_S - 1e-9
    if not np.any(late):
        return None
    error = braced_forces(data)[late] - data["desired_normal_force"]
    return float(np.sqrt(np.mean(error**2)))


_SeedRows = dict[str, list[dict[str, Any] | None]]
"""Each case's rows seed by seed, by its first seed's run id (``_seed_rows``)."""


def _seed_rows(study: Robustness, store: ResultsStore) -> _SeedRows:
    """Each case's rows, seed by seed, the braced runs' late force RMS added (a run every seed shares: read
    once)."""
    read: dict[str, dict[str, Any] | None] = {}
    out: _SeedRows = {}
    for case, first in study.runs.items():
        rows = []
        for spec in study.replicas.runs[first.run_id]:
            if spec.run_id not in read:
                row = store.row(spec.run_id)
                if row is not None and case.variant == BRACED.name:
                    row[FORCE_LATE] = late_force_rms(store, row)
                read[spec.run_id] = row
            rows.append(read[spec.run_id])
        out[first.run_id] = rows
    return out


def _rows(by_seed: _SeedRows, seed: int | None = None) -> dict[str, dict[str, Any]]:
    """Every case's row, by its first seed's run id: the median over the seeds (``study_runs.median_row``),
    or the ``seed``-th seed's (an index into the study's seeds)."""
    rows: dict[str, dict[str, Any]] = {}
    for first, seeds in by_seed.items():
        median = median_row(seeds if seed is None else seeds[seed : seed + 1])
        if median is not None:
            rows[first] = median
    return rows


def _value(row: dict[str, Any] | None, key: str) -> Any:
    if row is None:
        return "not run"
    if not is_ok(row):
        return "failed"
    return row.get(key)


# -- the report -------------------------------------------------------------------------------------
TABLE_HEADER = [
    "level",
    "law",
    "hand RMS braced [m]",
    "passive [m]",
    "free [m]",
    "force RMS braced [N]",
    f"after {HAND_ERROR_T_MIN_S:g} s [N]",
    "energy braced [J]",
    "passive [J]",
    "free [J]",
    "energy braced / free",
    "hand RMS braced / free",
    "energy braced / passive",
    "hand RMS braced / passive",
]


def _line(
    study: Robustness, rows: Mapping[str, dict[str, Any]], factor: Factor | None, level: Level, law: str
) -> list[Any]:
    braced, passive, free = (study.row(rows, factor, level, law, v.name) for v in VARIANTS)
    return [
        level.label,
        LAW_TEXT[law],
        _value(braced, HAND_RMS),
        _value(passive, HAND_RMS),
        _value(free, HAND_RMS),
        _value(braced, FORCE_RMS),
        _value(braced, FORCE_LATE),
        _value(braced, ENERGY),
        _value(passive, ENERGY),
        _value(free, ENERGY),
        ok_ratio(ENERGY, braced, free),
        ok_ratio(HAND_RMS, braced, free),
        ok_ratio(ENERGY, braced, passive),
        ok_ratio(HAND_RMS, braced, passive),
    ]


def _torque_table(study: Robustness, rows: Mapping[str, dict[str, Any]], factor: Factor | None) -> list[str]:
    if not study.torque_rows or (factor is not None and not factor.torque):
        return []
    points = [(None, NOMINAL_LEVEL)] + ([(factor, level) for level in factor.levels] if factor else [])
    table = []
    for where, level in points:
        for law in LAWS:
            row = study.row(rows, where, level, law, BRACED.name, TORQUE)
            table.append(
                [
                    level.label,
                    "force feedback" if law == FEEDBACK_LAW else LAW_TEXT[law],
                    _value(row, HAND_RMS),
                    _value(row, FORCE_RMS),
                    _value(row, FORCE_LATE),
                    _value(row, ENERGY),
                ]
            )
    header = [
        "level",
        "law",
        "hand RMS [m]",
        "force RMS [N]",
        f"after {HAND_ERROR_T_MIN_S:g} s [N]",
        "energy (mechanical) [J]",
    ]
    return ["Braced, torque input (direct drive: no voltage law to compensate):", "", markdown_table(header, table), ""]


def _factor_section(
    study: Robustness, store: ResultsStore, rows: Mapping[str, dict[str, Any]], number_: int, factor: Factor
) -> list[str]:
    table = [
        _line(study, rows, where, level, law)
        for where, level in ((None, NOMINAL_LEVEL), *((factor, lv) for lv in factor.levels))
        for law in LAWS
    ]
    figure = f"robustness_{factor.key}.png"
    draw_factor(study, store, rows, factor, figure)
    return [
        f"## {number_}. {factor.title}",
        "",
        f"{factor.models}.",
        "",
        markdown_table(TABLE_HEADER, table),
        "",
        *_torque_table(study, rows, factor),
        f"![hand and force RMS, energy ratios against {factor.axis}]({figure})",
        "",
    ]


def _span(values: Sequence[float]) -> str:
    lo, hi = min(values), max(values)
    return f"x{lo:.3g}" if f"{lo:.3g}" == f"{hi:.3g}" else f"x{lo:.3g}-{hi:.3g}"


def _listed(items: Sequence[str], most: int = 4) -> str:
    shown = list(items[:most]) + ([f"{len(items) - most} more"] if len(items) > most else [])
    return shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " and " + shown[-1]


def _named(level: Level) -> str:
    """A level in a sentence."""
    return "the nominal" if level is NOMINAL_LEVEL else level.label


def _pays_in(energy: float, hand: float | None) -> bool:
    """Bracing pays: less energy than the baseline, and a hand no less precise (when both have one)."""
    return energy < 1 and (hand is None or hand < 1)


def _verdicts(
    study: Robustness, rows: Mapping[str, dict[str, Any]], baseline: Variant
) -> list[tuple[str, str, float, float | None]]:
    """(law, condition, braced / baseline energy, hand RMS ratio) of every condition with an energy ratio."""
    out = []
    for law in LAWS:
        law_text = "the paper's law" if law == PAPER_LAW else "feedback"
        for factor, level in study.points():
            braced = study.row(rows, factor, level, law, BRACED.name)
            other = study.row(rows, factor, level, law, baseline.name)
            energy, hand = ok_ratio(ENERGY, braced, other), ok_ratio(HAND_RMS, braced, other)
            if energy is not None:
                out.append((law, f"{_named(level)} with {law_text}", energy, hand))
    return out


def _against(baseline: Variant) -> str:
    return "free space" if baseline is FREE_SPACE else "resting passively"


def _pays(study: Robustness, rows: Mapping[str, dict[str, Any]], baseline: Variant) -> str:
    """Against ``baseline`` (free space or passive): in how many conditions bracing uses less energy and keeps
    the hand more precise, by law; the ratios' ranges; where it does not (or, when it mostly does not, where it
    does; when it never does, where it wins on one of the two)."""
    counts = dict.fromkeys(LAWS, 0)
    judged = dict.fromkeys(LAWS, 0)
    energies: list[float] = []
    hands: list[float] = []
    misses: list[str] = []
    paid: list[str] = []
    halves: list[str] = []  # conditions where it wins on one of the two
    for law, where, energy, hand in _verdicts(study, rows, baseline):
        judged[law] += 1
        energies.append(energy)
        if hand is not None:
            hands.append(hand)
        if _pays_in(energy, hand):
            counts[law] += 1
            paid.append(where)
            continue
        worse = [f"energy x{energy:.3g}"] if energy >= 1 else []
        worse += [f"hand RMS x{hand:.3g}"] if hand is not None and hand >= 1 else []
        misses.append(f"{where} ({', '.join(worse)})")
        if energy < 1 or (hand is not None and hand < 1):
            better = f"energy x{energy:.3g}" if energy < 1 else f"hand RMS x{hand:.3g}"
            halves.append(f"{where} ({better})")
    if not energies:
        return ""
    against = _against(baseline)
    whose = "free space's" if baseline is FREE_SPACE else "the passive runs'"
    gains = "less energy and a more precise hand" if hands else "less energy"
    laws = {PAPER_LAW: "conditions with the paper's law", FEEDBACK_LAW: "with force feedback and thermal compensation"}
    tally = " and ".join(f"{counts[law]} of {judged[law]} {laws[law]}" for law in LAWS if judged[law])
    ratios = f"energy {_span(energies)}" + (f", hand RMS {_span(hands)}" if hands else "")
    text = f"against {against}, bracing pays ({gains}) in {tally} ({ratios} of {whose})"
    if paid and len(misses) <= len(paid):
        text += f"; it does not under {_listed(misses)}" if misses else ""
    elif paid:
        text += f"; it pays only under {_listed(paid)}"
    elif halves:
        text += f"; it wins on one of the two only under {_listed(halves)}"
    return text


def _feedback_forces(study: Robustness, rows: Mapping[str, dict[str, Any]]) -> list[tuple[float, str, float, float]]:
    """(feedback / paper, level, paper's, feedback's) braced force error of every condition where both ran and
    the paper's law's is not ~0."""
    forces = []
    for factor, level in study.points():
        before = force_error(study.row(rows, factor, level, PAPER_LAW, BRACED.name))
        after = force_error(study.row(rows, factor, level, FEEDBACK_LAW, BRACED.name))
        if before is not None and after is not None and before >= RATIO_FLOOR:
            forces.append((after / before, _named(level), before, after))
    return forces


def _buys(study: Robustness, rows: Mapping[str, dict[str, Any]]) -> str:
    """What force feedback + thermal compensation changes in the braced runs: the force error, the hand RMS,
    the energy; with torque input, under the model error that hurts most."""
    nominal_paper = study.row(rows, None, NOMINAL_LEVEL, PAPER_LAW, BRACED.name)
    nominal_feedback = study.row(rows, None, NOMINAL_LEVEL, FEEDBACK_LAW, BRACED.name)
    late = is_ok(nominal_paper) and number((nominal_paper or {}).get(FORCE_LATE))
    when = f"after {HAND_ERROR_T_MIN_S:g} s" if late else "over the run"
    forces = _feedback_forces(study, rows)
    hands: list[float] = []
    energies: list[float] = []
    for factor, level in study.points():
        paper = study.row(rows, factor, level, PAPER_LAW, BRACED.name)
        feedback = study.row(rows, factor, level, FEEDBACK_LAW, BRACED.name)
        for key, out in ((HAND_RMS, hands), (ENERGY, energies)):
            value = ok_ratio(key, feedback, paper)
            if value is not None:
                out.append(value)
    if not forces:
        return ""
    text = f"force feedback ({_gains(study.mode)}) with thermal compensation"
    start = force_error(nominal_paper), force_error(nominal_feedback)
    if start[0] is not None and start[1] is not None:
        text += f" takes the braced |f_n - f_nd| RMS {when} from {start[0]:.3g} N to {start[1]:.3g} N at the nominal"
    lower = [f for f in forces if f[0] < 1]
    median = statistics.median(f[0] for f in forces)
    text += f" and lowers it in {len(lower)} of {len(forces)} conditions (median x{median:.2g}"
    if lower:
        best = min(lower)
        text += f"; most under {best[1]}: {best[2]:.3g} -> {best[3]:.3g} N"
        least = max(lower)
        if least is not best:
            text += f", least under {least[1]}: {least[2]:.3g} -> {least[3]:.3g} N"
    text += ")"
    higher = [f"{f[1]} ({f[2]:.3g} -> {f[3]:.3g} N)" for f in sorted(forces, reverse=True) if f[0] >= 1]
    if higher:
        text += f", but raises it under {_listed(higher)}"
    changes = []
    if hands:
        changes.append(f"the hand RMS x{statistics.median(hands):.3g}")
    if energies:
        changes.append(f"the energy x{statistics.median(energies):.3g}")
    if changes:
        text += f", changing {' and '.join(changes)} (medians)"
    torque = _torque_effect(study, rows)
    return text + (f"; {torque}" if torque else "")


def _torque_effect(study: Robustness, rows: Mapping[str, dict[str, Any]]) -> str:
    """With torque input: the force error with and without feedback where the paper's law does worst."""
    if not study.torque_rows:
        return ""
    worst: tuple[float, str, float] | None = None
    for factor, level in study.points():
        if factor is not None and not factor.torque:
            continue
        paper = force_error(study.row(rows, factor, level, PAPER_LAW, BRACED.name, TORQUE))
        feedback = force_error(study.row(rows, factor, level, FEEDBACK_LAW, BRACED.name, TORQUE))
        if paper is None or feedback is None or paper < RATIO_FLOOR:
            continue  # exact to rounding (the model exact): nothing to buy
        if worst is None or paper > worst[0]:
            worst = (paper, _named(level), feedback)
    if worst is None:
        return ""
    return (
        f"with torque input ({_gains(TORQUE)}), under {worst[1]}, it takes that force error from {worst[0]:.3g} N "
        f"to {worst[2]:.3g} N"
    )


def over_seeds(study: Robustness, by_seed: _SeedRows) -> str:
    """With several seeds: in how many conditions bracing pays in every seed, against free space and against
    resting passively (``study_runs.holds_text``); nothing with one seed."""
    seeds = study.replicas.seeds
    if len(seeds) < 2:
        return ""
    per_seed = [_rows(by_seed, k) for k in range(len(seeds))]
    parts = []
    for baseline in (FREE_SPACE, PASSIVE):
        held: dict[str, list[bool]] = {}
        for rows in per_seed:
            for _, where, energy, hand in _verdicts(study, rows, baseline):
                held.setdefault(where, []).append(_pays_in(energy, hand))
        if held:
            parts.append(f"against {_against(baseline)}, bracing pays {holds_text(held, len(seeds))}")
    lowered: dict[str, list[bool]] = {}
    for rows in per_seed:
        for share, level, _, _ in _feedback_forces(study, rows):
            lowered.setdefault(level, []).append(share < 1)
    if lowered:
        parts.append(f"force feedback lowers the braced force error {holds_text(lowered, len(seeds))}")
    return ("Seed by seed: " + "; ".join(parts) + ".") if parts else ""


def answer(study: Robustness, rows: Mapping[str, dict[str, Any]]) -> str:
    """The report's one paragraph, from the numbers: where bracing still pays (against free space and against
    resting passively), and what force feedback buys."""
    parts = [p for p in (_pays(study, rows, FREE_SPACE), _pays(study, rows, PASSIVE), _buys(study, rows)) if p]
    if not parts:
        return ""
    sentences = [p[0].upper() + p[1:] + "." for p in parts]
    return " ".join(sentences)


def write_report(study: Robustness, output: Path, wall_time_s: float, executor: str, reused: int = 0) -> Path:
    """DIR/report.md and its figures from the runs in DIR."""
    import matplotlib  # imported where used: matplotlib ~460 ms (python -X importtime)

    matplotlib.use("Agg")
    store = ResultsStore(output)
    by_seed = _seed_rows(study, store)
    rows = _rows(by_seed)
    ok = sum(1 for row in rows.values() if is_ok(row))
    duration = study.duration if study.duration is not None else study.specs[0].duration
    compute = sum(float(row.get("wall_time_s") or 0.0) for row in rows.values())
    contacts = ", ".join(f"`{name}`" for name in study.braced)
    torque = " Braced runs in torque input too, for the model errors that apply to it." if study.torque_rows else ""
    said = answer(study, rows)
    gains = _gains(study.mode) + (f"; torque input {_gains(TORQUE)}" if study.torque_rows else "")
    lines = [
        f"# Robustness study: {study.config.name}",
        "",
        f"{len(study.specs)} in-process runs of {duration:g} s (the nodes' simulator and controller cores, "
        f"lockstep), {len(study.runs)} conditions: {ok} ok, {len(rows) - ok} failed"
        f"{'' if len(rows) == len(study.runs) else ', the rest not run'}. "
        f"{compute:.0f} s of run time in all; this report's invocation took {wall_time_s:.0f} s on {executor}"
        f"{f' ({reused} runs reused)' if reused else ''}. Every run's row: `results.csv` / `results.parquet`; its "
        "summary and arrays: `runs/<run id>/`.",
        "",
        f"The {'paper' if study.scenario == 'paper_4link' else study.scenario} scenario's task braced, "
        f"{PASSIVE.label} and in {FREE_SPACE.label}, {study.mode} input, one factor "
        "at a time around the nominal (the controller's model exact, exact sensing, no latency): each level with "
        f"the paper's law and with force feedback on the braced contact {contacts} (f_cmd = f_nd + kp (f_nd - "
        f"f_meas) + ki * integral, {gains}) plus thermal compensation of the voltage law; passive and free runs "
        f"have no brace task, so they take the thermal compensation only.{torque} Hand RMS over t >= "
        f"{HAND_ERROR_T_MIN_S:g} s; the braced contact's |f_n - f_nd| RMS over the whole run (summary.json's) and "
        f"after {HAND_ERROR_T_MIN_S:g} s (from the run's arrays); a ratio is n/a across input modes and to a "
        "baseline of ~0. Each factor's table starts with the nominal.",
        "",
        f"{window_text(duration)} {study.replicas.summary_text()}",
        "",
        "**Where does bracing still pay, and what does force feedback buy?** "
        + (said or "No run came back ok: no answer.")
        + (f" {seeded}" if (seeded := over_seeds(study, by_seed)) else ""),
        "",
    ]
    for k, factor in enumerate(study.factors, 1):
        lines += _factor_section(study, store, rows, k, factor)
    lines += _failures_section(rows)
    lines += warnings_section(dict(rows))
    path = output / REPORT
    path.write_text("\n".join(lines))
    study.replicas.write_runs(store)
    return path


def _failures_section(rows: Mapping[str, dict[str, Any]]) -> list[str]:
    """Each distinct error of the failed runs, once, with how many runs had it (their rows: results.csv)."""
    counts: dict[str, int] = {}
    for row in rows.values():
        if not is_ok(row):
            error = str(row.get("error") or "no error given")
            counts[error] = counts.get(error, 0) + 1
    if not counts:
        return []
    return [
        "## Failed runs",
        "",
        *[f"- {error} ({n} run{'s' if n > 1 else ''})" for error, n in counts.items()],
        "",
    ]
