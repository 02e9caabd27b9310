"""The paper study's report on the optimiser's answer: the optimum beside the file's setting (braced,
passive, free) and the grid's best cells, what it changed, and one sentence on what the numbers say."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bracing_analysis.ratios import ratio
from bracing_core.numbers import cell, markdown_table, number
from bracing_experiments.optimize_report import changes
from bracing_experiments.reporting import is_ok as _ok

if TYPE_CHECKING:
    from optuna.trial import FrozenTrial
from bracing_experiments.study_specs import (
    ENERGY,
    HAND_MAX,
    HAND_RMS,
    PAPER_SCENARIO,
    SEARCH_DIR,
    PlacementSearch,
    Study,
    _braced_row,
    _Cell,
    _grid_cells,
    _passive_row,
)


@dataclass
class _Beside:
    """The runs the optimum is set beside: the file's setting braced, passive and free, the grid's best cells."""

    where: str  # whose setting: "the paper's" | "the file's"
    setting: dict[str, Any] | None
    passive: dict[str, Any] | None
    free: dict[str, Any] | None
    best_cell: _Cell | None  # the grid's least energy
    best_feasible: _Cell | None  # ... within the hand RMS bound


def _beside(study: Study, rows: dict[str, dict[str, Any]], bound: float) -> _Beside:
    cells = _grid_cells(study, rows)
    best_cell = min(cells, key=lambda c: float(c[2][ENERGY])) if cells else None
    feasible = [c for c in cells if float(c[2][HAND_RMS]) <= bound]
    best_feasible = min(feasible, key=lambda c: float(c[2][ENERGY])) if feasible else None
    return _Beside(
        "the paper's" if study.scenario == PAPER_SCENARIO else "the file's",
        _braced_row(study, rows),
        _passive_row(study, rows),
        _braced_row(study, rows, braced=False),
        best_cell,
        best_feasible,
    )


def _search_row(name: str, force: Any, target: Any, row: dict[str, Any] | None, bound: float) -> list[Any]:
    """One line of the optimiser's table: the run's numbers and whether its hand RMS meets ``bound``."""
    if row is None or not _ok(row):
        return [name, force, target, f"failed: {row.get('error') if row else 'not run'}", "", "", ""]
    rms = row.get(HAND_RMS)
    return [name, force, target, row.get(ENERGY), rms, row.get(HAND_MAX), number(rms) and float(rms) <= bound]


def _search_table(study: Study, search: PlacementSearch, beside: _Beside) -> list[list[Any]]:
    """The file's setting (braced, passive, free), the grid's best cells and the optimum."""
    where, bound = beside.where, search.bound
    table = [
        _search_row(f"braced, {where} setting", study.desired, study.origin, beside.setting, bound),
        _search_row(f"passive, {where} setting (no brace task)", "n/a", "n/a", beside.passive, bound),
        _search_row(f"free, {where} setting (no contact)", "n/a", "n/a", beside.free, bound),
    ]
    best_cell, best_feasible = beside.best_cell, beside.best_feasible
    if best_cell is not None:
        table.append(_search_row("grid's best (least energy)", best_cell[1], best_cell[0], best_cell[2], bound))
    if best_feasible is not None and best_feasible is not best_cell:
        name = "grid's best within the bound"
        table.append(_search_row(name, best_feasible[1], best_feasible[0], best_feasible[2], bound))
    best = search.found.best if search.found is not None else None
    optimum = search.optimum
    if best is not None and optimum is not None:
        target = best.params[search.target] if search.target else study.origin
        table.append(
            _search_row(f"**optimum** (trial {best.number})", best.params[search.force], target, optimum, bound)
        )
    return table


def _search_paragraph(search: PlacementSearch) -> str:
    """What the search was and where its study lives."""
    found = search.found
    trials = found.trials if found is not None else 0
    ran = found.search.ran if found is not None else 0
    varies = " and ".join(f"`{v.name}` in [{v.low:.4g}, {v.high:.4g}]" for v in search.problem.varies)
    return (
        f"Least energy subject to hand RMS <= {search.bound:g} m over {varies} ({search.why}), searched by "
        f"bracing-optimize (Optuna's TPE, seed {search.seed}) with the grid's runs on the same executor: {trials} "
        f"trials ({ran} run by this invocation), the first at the grid's best cell within the bound. Its study and "
        f"trials: `{SEARCH_DIR}/{search.output.name}/` (the same command again reuses them; its `best.yaml` runs "
        "the optimum with `bracing-pair --config`)."
    )


def _optimum_against(
    study: Study, search: PlacementSearch, beside: _Beside, best: FrozenTrial, optimum: dict[str, Any], trials: int
) -> list[str]:
    """What the optimum changed against the file's setting and the grid's cell to beat, and what that says."""
    lines = []
    changed = {name: after for name, _, after in changes(search.problem, best)}
    best_cell, best_feasible = beside.best_cell, beside.best_feasible
    # The grid's cell to beat: its least energy within the bound (the optimum's own constraint).
    grid_name = "the grid's best cell" + ("" if best_feasible is best_cell else " within the bound")
    started = search.start is not None and best.params == search.start
    against = [(f"{beside.where} setting", study.desired, study.origin, beside.setting)]
    if best_feasible is not None and not started:
        against.append((grid_name, best_feasible[1], best_feasible[0], best_feasible[2]))
    for name, force, target, row in against:
        if row is None or not _ok(row):
            continue
        moves = [_move("f_nd", force, changed[search.force], "N", ".3g")]
        if search.target:
            moves.append(_move(f"target {study.axis}", target, changed[search.target], "m", ".3f"))
        energy, hand = ratio(ENERGY, optimum, row)[0], ratio(HAND_RMS, optimum, row)[0]
        lines.append(
            f"- Against {name}, the optimum {_joined(moves)}: energy x {cell(energy, 3)}, hand RMS x {cell(hand, 3)}."
        )
    if started:
        lines.append(f"- The optimum is the grid's cell the search started from: {trials} trials found nothing better.")
    grid_row = best_feasible[2] if best_feasible is not None else None
    sentence = _what_it_says(study, beside.where, beside.setting, beside.passive, optimum, grid_row, grid_name)
    if sentence:
        lines += ["", f"**What the numbers say**: {sentence}"]
    return lines


def _search_lines(
    study: Study, rows: dict[str, dict[str, Any]], search: PlacementSearch | None, note: str
) -> list[str]:
    """The optimiser's answer beside the grid's best cell, the file's setting, passive and free; what it
    changed; one sentence on what the numbers say."""
    lines = ["### The optimiser's answer", ""]
    if search is None:
        return [*lines, f"Not searched{f': {note}' if note else ''}.", ""]
    found, optimum = search.found, search.optimum
    bound = search.bound
    header = ["run", "f_nd [N]", f"target {study.axis} [m]", "energy [J]", "hand RMS [m]", "hand max [m]"]
    beside = _beside(study, rows, bound)
    table = _search_table(study, search, beside)
    lines += [_search_paragraph(search), "", markdown_table([*header, f"hand RMS <= {bound:g} m"], table), ""]
    best = found.best if found is not None else None
    if found is None or best is None or optimum is None:
        return [*lines, "No trial met the bound: no optimum.", ""]
    return [*lines, *_optimum_against(study, search, beside, best, optimum, found.trials), ""]


def _what_it_says(
    study: Study,
    where: str,
    setting: dict[str, Any] | None,
    passive: dict[str, Any] | None,
    optimum: dict[str, Any],
    grid_best: dict[str, Any] | None,
    grid_name: str,
) -> str:
    """One sentence: does resting passively beat bracing at the file's force, does the optimum beat both."""

    def usable(row: dict[str, Any] | None) -> bool:
        return row is not None and _ok(row) and number(row.get(ENERGY)) and number(row.get(HAND_RMS))

    def mm(row: dict[str, Any]) -> str:
        return f"{float(row[HAND_RMS]) * 1e3:.3g} mm"

    parts = []
    braced = f"bracing at {where} {study.desired:g} N"
    if usable(setting) and usable(passive):
        assert setting is not None and passive is not None
        cheaper = float(passive[ENERGY]) < float(setting[ENERGY])
        precise = float(passive[HAND_RMS]) < float(setting[HAND_RMS])
        parts.append(
            f"resting passively uses {'less' if cheaper else 'more'} energy than {braced} "
            f"({float(passive[ENERGY]):.4g} J against {float(setting[ENERGY]):.4g} J) and is "
            f"{'more' if precise else 'less'} precise ({mm(passive)} against {mm(setting)})"
        )
    others = [(braced, setting), ("resting passively", passive)]
    beaten = [name for name, row in others if usable(row) and float(optimum[ENERGY]) < float(row[ENERGY])]  # type: ignore[index]
    compared = [name for name, row in others if usable(row)]
    if compared:
        if len(beaten) == len(compared):
            verdict = "uses less energy than " + ("both" if len(compared) == 2 else compared[0])
        elif beaten:
            verdict = f"uses less energy than {beaten[0]} but not than {next(n for n in compared if n not in beaten)}"
        else:
            verdict = "uses less energy than neither"
        grid = ""
        if usable(grid_best):
            assert grid_best is not None
            share = float(optimum[ENERGY]) / float(grid_best[ENERGY])
            grid = f", {share:.2f} x the energy of {grid_name} ({float(grid_best[ENERGY]):.4g} J)"
        parts.append(f"the optimum ({float(optimum[ENERGY]):.4g} J at {mm(optimum)}) {verdict}{grid}")
    if not parts:
        return ""
    text = "; ".join(parts) + "."
    return text[0].upper() + text[1:]


def _move(what: str, before: float, after: float, unit: str, spec: str) -> tuple[str, str]:
    """(verb, what): ``what`` from ``before`` to ``after`` (or kept), for the optimum's changes."""
    if f"{before:{spec}}" == f"{after:{spec}}":
        return "keeps", f"{what} at {after:{spec}} {unit}"
    return "moves", f"{what} {before:{spec}} -> {after:{spec}} {unit}"


def _joined(moves: Sequence[tuple[str, str]]) -> str:
    """``moves`` as a clause, a verb said once for a run of changes that share it."""
    parts = [f"{verb} {what}" if k == 0 or moves[k - 1][0] != verb else what for k, (verb, what) in enumerate(moves)]
    return " and ".join(parts)
