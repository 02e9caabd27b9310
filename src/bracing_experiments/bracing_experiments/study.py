"""bracing-study: the paper's comparisons as one report, from in-process runs in parallel.

    bracing-study paper --output DIR [--duration S] [--workers N] [--scheduler ADDRESS] [--set KEY=VALUE ...]
                        [--positions N] [--span M] [--trials N]
    bracing-study config/hyper_7link.yaml --output DIR
    bracing-study robustness --output DIR [--duration S] [--workers N | --scheduler ADDRESS] [--set KEY=VALUE ...]

``robustness`` is the robustness study (bracing_experiments.robustness: the paper scenario under model error,
real sensing and command latency, with and without force feedback; ``bracing-study robustness --help``); the
rest of this docstring is the paper study's.

1. bracing: braced vs passive (make run's: no brace task, the surfaces kept as obstacles the arm can
   rest on) vs free (no contacts), voltage and torque input, with and without null-space gravity
   compensation: hand RMS / max error, energy consumed, copper loss, the hottest motor;
2. gains: every PD gain (hand and brace, Kp and Kd) scaled by 1, 0.5, 0.2, 0.1, torque and
   voltage input: force error (max, RMS) against the position errors (paper Sec. 4, Figs. 9-16);
3. placement: energy and hand error over a grid of brace targets along the first brace axis of
   the first contact and of desired normal forces, the best cell marked; then bracing-optimize's
   search over the same two axes (least energy subject to a hand RMS bound; ``--trials N``), its
   optimum beside the grid's best cell, the file's setting and the passive run.

Writes DIR/report.md with its figures (bracing.png, gains.png, placement.png), and the sweep's
DIR/results.parquet, DIR/results.csv and DIR/runs/ (the same command again reuses finished runs), and
the optimiser's study in DIR/optimize/<problem>/ (study.db, trials.csv, best.yaml, report.md: the same
command again reuses its trials, and runs only those a larger --trials asks for).
Exit 0 when every run is ok, 1 when one failed (the report is still written, its cells say which),
2 on a configuration error before any run (every run's configuration and task rank are checked first).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bracing_analysis.ratios import TEMPERATURE_KEY, ratio, temperature_saving, temperature_saving_text
from bracing_analysis.summary import HAND_ERROR_T_MIN_S
from bracing_core import schema
from bracing_core.config import ContactConfig, SharedConfig
from bracing_core.numbers import cell, markdown_table, number
from bracing_core.overrides import CONTROLLER, NodeOverrides, node_params, parse_single, route
from bracing_core.params import ConfigError
from bracing_core.rollout import build_scenario
from bracing_core.variants import PASSIVE
from bracing_experiments.cli import (
    EXIT_FAILED,
    add_study_options,
    check_options,
    config_error,
    handle_stop_signals,
    interrupted,
    study_exit,
)
from bracing_experiments.executors import Executor, make_executor
from bracing_experiments.experiment import FORCE_MAX_ERROR_KEY, RunSpec
from bracing_experiments.optimize import Optimum, Problem, build_problem, changes, optimize
from bracing_experiments.reporting import braced_forces as _braced_forces
from bracing_experiments.reporting import is_ok as _ok
from bracing_experiments.reporting import resolve_scenario
from bracing_experiments.reporting import run_arrays as _arrays
from bracing_experiments.reporting import warnings_section as _warnings_section
from bracing_experiments.robustness import STUDY as ROBUSTNESS
from bracing_experiments.robustness import main as robustness_main
from bracing_experiments.sweep import ResultsStore, make_spec, run_sweep

if TYPE_CHECKING:
    from optuna.trial import FrozenTrial

PAPER_SCENARIO = "paper_4link"
"""The scenario whose figures the paper has: only its report cites them."""
GAIN_SCALES = (1.0, 0.5, 0.2, 0.1)
FORCE_SCALES = (0.5, 1.0, 2.0)  # x the file's desired normal force
REPORT = "report.md"
ENERGY, HAND_RMS, HAND_MAX = "energy_consumed_j", "hand_rms_error_m", "hand_max_error_m"
PAPER_SEARCH = ((0.0, 40.0), (0.35, 0.85))
"""The paper arm's search (issue 28): f_nd [N] and the elbow target's y [m]."""
PAPER_HAND_RMS_BOUND = 0.03
"""[m] the paper arm's precision bound on the optimum (issue 28): hand RMS <= 30 mm."""
SEARCH_WIDEN = 5 / 3
"""Other scenarios: the target's search range is the grid's (start +- span) widened by this (the
paper's 0.35-0.85 m is its start 0.588 m +- 0.25 m, 5/3 of the grid's 0.15 m), the force's 0 to
twice the grid's largest (the paper's 0-40 N)."""
SEARCH_DIR = "optimize"
SEARCH_TRIALS = 40
"""--trials' default: the paper study's search beats the grid's best in it (README: what it finds)."""
SEARCH_SEED = 0


@dataclass
class Study:
    config: Path
    duration: float | None
    bracing: list[RunSpec]
    gains: list[RunSpec]
    placement: list[RunSpec]
    contact: str  # the placement study's contact
    axis: str  # ... and the brace axis its targets move along
    targets: list[float]  # [m] along that axis
    forces: list[float]  # [N]
    passive: list[RunSpec] = field(default_factory=list)  # variants.PASSIVE beside each case of `bracing`
    base: dict[str, Any] = field(default_factory=dict)  # the --set overrides of every run
    setting: tuple[str, bool] = ("voltage", False)  # the file's input mode and gravity compensation (the grid's)
    origin: float = 0.0  # the contact's target along the axis, as the file has it [m]
    desired: float = 0.0  # its desired normal force, as the file has it [N]
    span: float = 0.0  # the grid's targets: origin +- span [m]

    @property
    def specs(self) -> list[RunSpec]:
        return [*self.bracing, *self.passive, *self.gains, *self.placement]

    @property
    def axis_index(self) -> int:
        return "xyz".index(self.axis)

    @property
    def scenario(self) -> str:
        return self.config.stem

    def paper(self, text: str) -> str:
        """``text`` (a citation of the paper's figures) for the paper's scenario, else nothing."""
        return text if self.scenario == PAPER_SCENARIO else ""


def _scaled(values: Any, scale: float) -> list[float]:
    return [float(v) * scale for v in (values if isinstance(values, list) else [values])]


_MakeSpec = Callable[[str, dict[str, Any], dict[str, Any]], RunSpec]
"""(comparison, labels, overrides) -> the run's spec, with the study's --set overrides under its own."""


def _bracing_specs(spec: _MakeSpec) -> list[RunSpec]:
    """Comparison 1: braced and free, both inputs, with and without gravity compensation."""
    return [
        spec(
            "bracing",
            {"bracing": with_contacts, "input_mode": mode, "gravity_compensation": compensation},
            {
                "input_mode": mode,
                "gravity_compensation": compensation,
                **({} if with_contacts else {"contacts.names": []}),
            },
        )
        for with_contacts in (True, False)
        for mode in ("voltage", "torque")
        for compensation in (False, True)
    ]


def _passive_specs(spec: _MakeSpec) -> list[RunSpec]:
    """Resting passively (variants.PASSIVE) beside each input and compensation of comparison 1."""
    return [
        spec(
            "passive",
            {"input_mode": mode, "gravity_compensation": compensation},
            {"input_mode": mode, "gravity_compensation": compensation, **PASSIVE.overrides()},
        )
        for mode in ("voltage", "torque")
        for compensation in (False, True)
    ]


def _gain_specs(
    spec: _MakeSpec, ctl: dict[str, Any], contacts: Sequence[ContactConfig], gain_scales: Sequence[float]
) -> list[RunSpec]:
    """Comparison 2: every PD gain (hand and each contact's, kp and kd) scaled, both inputs."""
    gains = []
    for mode in ("torque", "voltage"):
        for scale in gain_scales:
            gain_overrides: dict[str, Any] = {
                "input_mode": mode,
                "hand.kp": _scaled(ctl["hand.kp"], scale),
                "hand.kd": _scaled(ctl["hand.kd"], scale),
            }
            for contact in contacts:
                for gain in ("kp", "kd"):
                    key = f"contacts.{contact.name}.{gain}"
                    gain_overrides[key] = _scaled(ctl.get(key, []), scale)
            gains.append(spec("gains", {"input_mode": mode, "gain_scale": scale}, gain_overrides))
    return gains


def _brace_origin(config: Path, routed: NodeOverrides, shared: SharedConfig, contact: ContactConfig) -> np.ndarray:
    """The contact's brace target as the file has it, else where its point starts (q = 0)."""
    scenario = build_scenario(config, shared=routed.shared, sim=routed.simulator, with_controller=False)
    start = scenario.sim.evaluate(np.zeros(scenario.sim.n)).contacts.positions
    return np.array(contact.target if contact.target is not None else start[shared.contacts.index(contact)])


def _placement_specs(
    spec: _MakeSpec, contact: str, origin: np.ndarray, axis: int, targets: Sequence[float], forces: Sequence[float]
) -> list[RunSpec]:
    """Comparison 3: the contact's target moved along ``axis`` to each of ``targets``, at each desired force."""
    placement = []
    for force in forces:
        for target in targets:
            point = origin.copy()
            point[axis] = target
            placement.append(
                spec(
                    "placement",
                    {"brace_target": round(target, 6), "desired_normal_force": force},
                    {
                        f"contacts.{contact}.target": [float(v) for v in point],
                        f"contacts.{contact}.desired_normal_force": force,
                    },
                )
            )
    return placement


def build_study(
    config: Path,
    duration: float | None = None,
    base: dict[str, Any] | None = None,
    positions: int = 5,
    span: float = 0.15,
    force_scales: Sequence[float] = FORCE_SCALES,
    gain_scales: Sequence[float] = GAIN_SCALES,
) -> Study:
    """Every run of the three comparisons, validated. ``base``: overrides applied to all runs."""
    base = dict(base or {})
    routed = route(base)
    ctl = node_params(config, routed)[CONTROLLER]
    shared = SharedConfig.from_values(schema.read("controller", ctl), [config.resolve().parent])
    braced = [c for c in shared.contacts if c.brace_axes and c.desired_normal_force]
    if not braced:
        raise ConfigError("contacts.names: the study needs a bracing contact (one with brace_axes and a desired force)")

    def spec(comparison: str, labels: dict[str, Any], overrides: dict[str, Any]) -> RunSpec:
        return make_spec(config, {"comparison": comparison, **labels}, duration, overrides={**base, **overrides})

    bracing = _bracing_specs(spec)
    passive = _passive_specs(spec)
    gains = _gain_specs(spec, ctl, shared.contacts, gain_scales)
    contact = braced[0]
    axis = contact.brace_axes[0]
    origin = _brace_origin(config, routed, shared, contact)
    offsets = np.linspace(-span, span, positions) if positions > 1 else np.zeros(1)
    targets = [float(origin[axis] + d) for d in offsets]
    desired = contact.desired_normal_force
    assert desired is not None  # a braced contact (study_specs picks one)
    forces = [desired * s for s in force_scales]
    placement = _placement_specs(spec, contact.name, origin, axis, targets, forces)
    values = schema.read("controller", ctl)
    return Study(
        config,
        duration,
        bracing,
        gains,
        placement,
        contact.name,
        "xyz"[axis],
        targets,
        forces,
        passive=passive,
        base=base,
        setting=(str(values["input_mode"]), bool(values["gravity_compensation"])),
        origin=float(origin[axis]),
        desired=float(desired),
        span=float(span) if positions > 1 else 0.0,
    )


# -- the optimiser over the grid's axes -----------------------------------------------------------------
@dataclass
class PlacementSearch:
    """bracing-optimize over the placement grid's two axes: the problem, where its study lives, what it found."""

    problem: Problem
    output: Path  # its study's directory (DIR/optimize/<problem key>)
    force: str  # the varied parameters' names (Vary.name)
    target: str | None  # None: the grid has one target, only the force varies
    bound: float  # [m] hand RMS bound
    why: str  # where the ranges and the bound come from
    start: dict[str, float] | None = None  # the grid's cell it tries first
    found: Optimum | None = None

    @property
    def optimum(self) -> dict[str, Any] | None:
        """The optimum trial's row (every metric of its run), or None."""
        best = self.found.best if self.found is not None else None
        return dict(best.user_attrs["row"]) if best is not None else None


def _braced_row(study: Study, rows: dict[str, dict[str, Any]], braced: bool = True) -> dict[str, Any] | None:
    """Comparison 1's braced (or free) run at the file's setting: the grid's input mode and compensation."""
    for spec in study.bracing:
        v = spec.varied
        if (v["bracing"], v["input_mode"], v["gravity_compensation"]) == (braced, *study.setting):
            return rows.get(spec.run_id)
    return None


def _passive_row(study: Study, rows: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    """The passive run at the file's setting."""
    for spec in study.passive:
        if (spec.varied["input_mode"], spec.varied["gravity_compensation"]) == study.setting:
            return rows.get(spec.run_id)
    return None


_Cell = tuple[float, float, dict[str, Any]]
"""(target [m], force [N], row) of a placement run (_grid_cells)."""


def _grid_cells(study: Study, rows: dict[str, dict[str, Any]]) -> list[_Cell]:
    """(target, force, row) of every placement run that came back ok with an energy and a hand error."""
    cells = []
    for k, spec in enumerate(study.placement):
        i, j = divmod(k, len(study.targets))
        row = rows.get(spec.run_id)
        if row is not None and _ok(row) and number(row.get(ENERGY)) and number(row.get(HAND_RMS)):
            cells.append((study.targets[j], study.forces[i], row))
    return cells


_Ranges = list[tuple[tuple[float, float], tuple[float, float] | None]]
"""(force, target) ranges [N], [m] of the search, the first the scenario takes; target None: only the force varies."""


def _search_bound(study: Study, rows: dict[str, dict[str, Any]]) -> tuple[float, _Ranges, str]:
    """The hand RMS bound [m], the ranges to try and where they come from (placement_search's docstring)."""
    if study.scenario == PAPER_SCENARIO and study.axis == "y":
        return PAPER_HAND_RMS_BOUND, [(PAPER_SEARCH[0], PAPER_SEARCH[1])], "the paper arm's problem"
    braced = _braced_row(study, rows)
    if braced is None or not _ok(braced) or not number(braced.get(HAND_RMS)):
        raise ConfigError("no hand RMS bound: the file's braced run (comparison 1) did not come back ok")
    bound = math.ceil(float(braced[HAND_RMS]) * 1e4) / 1e4
    forces = (0.0, 2.0 * max(study.forces))
    ranges: _Ranges
    if study.span > 0:
        wide = SEARCH_WIDEN * study.span
        ranges = [
            (forces, (study.origin - wide, study.origin + wide)),
            (forces, (min(study.targets), max(study.targets))),
        ]
    else:
        ranges = [(forces, None)]  # one target: only the force varies
    why = (
        f"f_nd from 0 to twice the grid's largest, the target over the grid's span widened x "
        f"{SEARCH_WIDEN:.3g} (the grid's own when the scenario refuses that), hand RMS no worse than the "
        f"file's braced run ({float(braced[HAND_RMS]) * 1e3:.3g} mm, rounded up to {bound * 1e3:g} mm)"
    )
    return bound, ranges, why


def _search_problem(study: Study, force: str, target: str, bound: float, ranges: _Ranges) -> tuple[Problem, list[str]]:
    """The optimiser's problem over the first of ``ranges`` it takes, and why it refused those before."""
    refused: list[str] = []
    for force_range, target_range in ranges:
        vary = [f"{force}={force_range[0]:g}:{force_range[1]:g}"]
        if target_range is not None:
            vary.append(f"{target}={target_range[0]:.6g}:{target_range[1]:.6g}")
        try:
            problem = build_problem(
                study.config, vary, [ENERGY], [f"{HAND_RMS}<={bound:g}"], study.duration, base=study.base
            )
            return problem, refused
        except ConfigError as exc:
            refused.append(str(exc))
    raise ConfigError("the optimiser's ranges are refused: " + "; ".join(refused))


def _search_start(search: PlacementSearch, cells: list[_Cell]) -> dict[str, float] | None:
    """The grid's least-energy cell within the bound, if any and inside the search's ranges."""
    feasible = [cell for cell in cells if float(cell[2][HAND_RMS]) <= search.bound]
    if not feasible:
        return None
    cell_target, cell_force, _ = min(feasible, key=lambda cell: float(cell[2][ENERGY]))
    point = {search.force: cell_force, **({search.target: cell_target} if search.target else {})}
    inside = all(v.low <= point[v.name] <= v.high for v in search.problem.varies)
    return point if inside else None


def placement_search(study: Study, rows: dict[str, dict[str, Any]], output: Path) -> PlacementSearch:
    """The optimiser's problem over the grid's axes (least energy subject to a hand RMS bound), checked;
    ConfigError when there is none (no bound: the file's braced run failed; a range the scenario refuses).

    The paper arm: f_nd in [0, 40] N, the elbow target's y in [0.35, 0.85] m, hand RMS <= 30 mm. Other
    scenarios: f_nd in [0, 2 x the grid's largest], the target in the grid's range widened by
    SEARCH_WIDEN (the grid's own if the scenario refuses that), hand RMS no worse than the file's
    braced run (rounded up to 0.1 mm). The search starts at the grid's best feasible cell."""
    cells = _grid_cells(study, rows)
    if not cells:
        raise ConfigError("no placement run came back with an energy and a hand error (hand errors start at t = 2 s)")
    contact, axis = study.contact, study.axis_index
    force = f"contacts.{contact}.desired_normal_force"
    target = f"contacts.{contact}.target[{axis}]"
    bound, ranges, why = _search_bound(study, rows)
    problem, refused = _search_problem(study, force, target, bound, ranges)
    if refused:
        why += f" (the widened target range was refused: {refused[0]}; the grid's own used)"
    search = PlacementSearch(
        problem,
        output / SEARCH_DIR / problem.key,
        force,
        target if len(problem.varies) > 1 else None,
        bound,
        why,
    )
    search.start = _search_start(search, cells)
    return search


def run_placement_search(
    search: PlacementSearch, executor: Executor, trials: int, progress: bool = True, seed: int = SEARCH_SEED
) -> PlacementSearch:
    """Resume or start the search's study (bracing-optimize's, in ``search.output``) up to ``trials``
    on ``executor``; a finished study runs nothing again."""
    search.found = optimize(
        search.problem,
        search.output,
        executor,
        trials,
        progress=progress,
        seed=seed,
        references=False,  # the study has the file's setting, passive and free runs itself
        first=[search.start] if search.start else [],
    )
    return search


# -- the report ------------------------------------------------------------------------------------
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
    header = [
        "bracing",
        "input",
        "gravity comp.",
        "hand RMS [m]",
        "hand max [m]",
        "energy [J]",
        "copper loss [J]",
        "hottest motor [degC]",
    ]
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
        markdown_table(
            [
                "input",
                "gravity comp.",
                "energy braced / free",
                "hand RMS braced / free",
                "energy braced / passive",
                "hand RMS braced / passive",
                "hottest motor, braced",
            ],
            ratios,
        ),
        "",
        *[f"- {line}" for line in findings],
        "",
        "![hand error and energy over time, braced, passive and free](bracing.png)",
        "",
    ]
    _draw_bracing(study, store, rows)
    return lines


def _draw_bracing(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(11, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: braced, passive and free")
    error_ax, energy_ax = fig.subplots(1, 2)
    colours = {
        ("voltage", False): "tab:blue",
        ("voltage", True): "tab:cyan",
        ("torque", False): "tab:red",
        ("torque", True): "tab:orange",
    }
    runs = [(spec, "braced" if spec.varied["bracing"] else "free") for spec in study.bracing]
    runs += [(spec, "passive") for spec in study.passive]
    for spec, kind in runs:
        if not _ok(rows.get(spec.run_id)):
            continue
        data = _arrays(store, spec.run_id)
        if data is None:
            continue
        v = spec.varied
        gravity = "g comp." if v["gravity_compensation"] else "no g comp."
        label = f"{kind}, {v['input_mode']}, {gravity}"
        style = dict(
            color=colours[(v["input_mode"], v["gravity_compensation"])],
            ls={"braced": "-", "free": "--", "passive": ":"}[kind],
        )
        error = np.linalg.norm(data["hand_desired"] - data["hand_actual"], axis=1)
        error_ax.plot(data["time"], error, label=label, lw=1.2, **style)
        energy_ax.plot(data["time"], data["energy_consumed"], label=label, lw=1.2, **style)
    error_ax.set(title="hand error |r_hd - r_h|", xlabel="time [s]", ylabel="[m]", yscale="log")
    energy_ax.set(title="energy consumed (torque input: mechanical)", xlabel="time [s]", ylabel="[J]", yscale="log")
    for ax in (error_ax, energy_ax):
        ax.grid(True, alpha=0.4)
    energy_ax.legend(fontsize=6, loc="lower right", ncol=2)
    fig.savefig(store.output / "bracing.png", dpi=110)


def _gains_section(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> list[str]:
    header = [
        "input",
        "gain scale",
        "force max err [N]",
        "force RMS err [N]",
        "hand RMS [m]",
        "hand max [m]",
        "brace RMS [m]",
    ]
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
    _draw_gains(study, store, rows)
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


def _draw_gains(study: Study, store: ResultsStore, rows: dict[str, dict[str, Any]]) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(14, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: gains scaled together")
    force_ax, position_ax, series_ax = fig.subplots(1, 3)
    colours = {"torque": "tab:red", "voltage": "tab:blue"}
    for mode in ("torque", "voltage"):
        points = [
            (s.varied["gain_scale"], rows[s.run_id])
            for s in study.gains
            if s.varied["input_mode"] == mode and _ok(rows.get(s.run_id))
        ]
        if not points:
            continue
        scales = [p[0] for p in points]
        force = [max(float(p[1].get(FORCE_MAX_ERROR_KEY) or 0.0), 1e-16) for p in points]
        force_ax.plot(scales, force, "o-", color=colours[mode], label=f"{mode}: max |f_n - f_nd|")
        for key, marker, name in (("hand_rms_error_m", "o-", "hand RMS"), ("brace_rms_error_m", "s--", "brace RMS")):
            position_ax.plot(
                scales, [p[1].get(key) for p in points], marker, color=colours[mode], label=f"{mode}: {name}"
            )
    for spec in study.gains:
        if spec.varied["input_mode"] != "voltage" or not _ok(rows.get(spec.run_id)):
            continue
        data = _arrays(store, spec.run_id)
        if data is not None and data["desired_normal_force"].size:
            series_ax.plot(
                data["time"], _braced_forces(data)[:, 0], lw=1.0, label=f"voltage, x{spec.varied['gain_scale']:g}"
            )
            desired = float(data["desired_normal_force"][0])
    if series_ax.lines:
        series_ax.axhline(desired, color="tab:red", ls="--", lw=1.0, label="f_nd (torque input: every run)")
    force_ax.axhline(np.finfo(float).eps * 10, color="grey", ls=":", lw=1.0)
    force_ax.set(
        title="force error (torque input: machine precision)",
        xlabel="gain scale",
        ylabel="[N]",
        xscale="log",
        yscale="log",
    )
    position_ax.set(title="position errors", xlabel="gain scale", ylabel="[m]", xscale="log")
    series_ax.set(title="normal force, voltage input" + study.paper(" (Fig. 16)"), xlabel="time [s]", ylabel="f_n [N]")
    for ax in (force_ax, position_ax, series_ax):
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=7)
    fig.savefig(store.output / "gains.png", dpi=110)


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
    _draw_placement(study, store, grids, point)
    return lines


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
        f"bracing-optimize (Optuna's TPE, seed {SEARCH_SEED}) with the grid's runs on the same executor: {trials} "
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


def _grid_position(value: float, ticks: Sequence[float]) -> float:
    """``value`` on an image axis whose ticks sit at 0, 1, ...: piecewise linear between them,
    extended past the ends by the end intervals (an optimum outside the grid lands outside it)."""
    if len(ticks) < 2:
        return 0.0
    k = int(np.clip(np.searchsorted(ticks, value) - 1, 0, len(ticks) - 2))
    return k + (value - ticks[k]) / (ticks[k + 1] - ticks[k])


def _draw_placement(
    study: Study, store: ResultsStore, grids: dict[str, np.ndarray], optimum: tuple[float, float] | None
) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(11, 4.0), layout="constrained")
    fig.suptitle(f"{study.scenario}: brace placement and force")
    axes = fig.subplots(1, 2)
    for ax, (key, title) in zip(axes, ((ENERGY, "energy consumed [J]"), (HAND_RMS, "hand RMS error [m]")), strict=True):
        grid = grids[key]
        image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        fig.colorbar(image, ax=ax)
        ax.set_xticks(range(len(study.targets)), [f"{t:.3f}" for t in study.targets])
        ax.set_yticks(range(len(study.forces)), [f"{f:g}" for f in study.forces])
        ax.set(title=title, xlabel=f"brace target {study.axis} [m]", ylabel="desired normal force [N]")
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                text = f"{grid[i, j]:.3g}" if np.isfinite(grid[i, j]) else "failed"
                ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white")
        if np.isfinite(grid).any():
            i, j = (int(x) for x in np.unravel_index(np.nanargmin(grid), grid.shape))
            ax.plot(
                j,
                i,
                marker="*",
                markersize=22,
                markerfacecolor="none",
                markeredgecolor="red",
                markeredgewidth=2,
                ls="none",
                label="grid's least",
            )
        if optimum is not None:
            x, y = _grid_position(optimum[0], study.targets), _grid_position(optimum[1], study.forces)
            ax.plot(
                x,
                y,
                marker="X",
                markersize=13,
                color="magenta",
                markeredgecolor="white",
                ls="none",
                label=f"optimum ({study.axis} {optimum[0]:.3f} m, {optimum[1]:.3g} N)",
            )
            ax.set_xlim(min(-0.5, x - 0.4), max(len(study.targets) - 0.5, x + 0.4))
            ax.set_ylim(min(-0.5, y - 0.4), max(len(study.forces) - 0.5, y + 0.4))
        ax.legend(fontsize=7, loc="lower left", framealpha=0.8, markerscale=0.6)
    fig.savefig(store.output / "placement.png", dpi=110)


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
    rows = {spec.run_id: row for spec in study.specs if (row := store.row(spec.run_id)) is not None}
    ok = sum(1 for row in rows.values() if _ok(row))
    duration = study.duration if study.duration is not None else study.specs[0].duration
    compute = sum(float(row.get("wall_time_s") or 0.0) for row in rows.values())
    lines = [
        f"# Bracing study: {study.config.name}",
        "",
        f"{len(study.specs)} in-process runs of {duration:g} s (the nodes' simulator and controller cores, "
        f"lockstep); {ok} ok, {len(rows) - ok} failed. {compute:.0f} s of run time in all; this report's "
        f"invocation took {wall_time_s:.0f} s on {executor}{f' ({reused} runs reused)' if reused else ''}"
        f"{_search_count(search)}. "
        "Every run's row: `results.csv` / `results.parquet`; its summary and arrays: `runs/<run id>/`.",
        "",
        *_bracing_section(study, store, rows),
        *_gains_section(study, store, rows),
        *_placement_section(study, store, rows, search, search_note),
        *_warnings_section(rows),
    ]
    path = output / REPORT
    path.write_text("\n".join(lines))
    return path


def _search_count(search: PlacementSearch | None) -> str:
    if search is None or search.found is None:
        return ""
    return f", the optimiser's {search.found.trials} trials included ({search.found.search.ran} run now)"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bracing-study", description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument(
        "scenario",
        help=f"'paper' or a scenario params file; '{ROBUSTNESS}': the robustness study ({ROBUSTNESS} --help)",
    )
    add_study_options(parser)
    parser.add_argument("--positions", type=int, default=5, help="brace targets in the placement grid")
    parser.add_argument("--span", type=float, default=0.15, help="placement targets: start position +- span [m]")
    parser.add_argument(
        "--trials",
        type=int,
        default=SEARCH_TRIALS,
        help=f"the optimiser's trials over the placement axes (default {SEARCH_TRIALS}; 0: no search)",
    )
    args = parser.parse_args(argv)
    if args.trials < 0:
        parser.error("--trials must be >= 0")
    check_options(parser, args)  # (--workers >= 1: checked since the options are one with the other commands')
    if args.positions < 1 or args.span < 0:
        parser.error("--positions must be >= 1 and --span >= 0")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == [ROBUSTNESS]:  # its own options (bracing_experiments.robustness)
        return robustness_main(argv[1:])
    args = parse_args(argv)
    handle_stop_signals()
    start = time.perf_counter()
    try:
        config = resolve_scenario(args.scenario)
        study = build_study(config, args.duration, parse_single(args.sets), args.positions, args.span)
        ResultsStore(args.output).check_manifest(config)
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        return config_error("bracing-study", exc)
    try:
        with executor:
            where = executor.description
            print(f"bracing-study: {len(study.specs)} runs of {config} on {where}", file=sys.stderr)
            result = run_sweep(study.specs, args.output, executor, progress=not args.no_progress)
            search, note = None, "--trials 0" if args.trials == 0 else ""
            if args.trials > 0:
                store = ResultsStore(args.output)
                rows = {spec.run_id: row for spec in study.specs if (row := store.row(spec.run_id)) is not None}
                try:
                    search = placement_search(study, rows, args.output)
                except ConfigError as exc:
                    note = str(exc)
                    print(f"bracing-study: no optimisation: {note}", file=sys.stderr)
                if search is not None:
                    run_placement_search(search, executor, args.trials, progress=not args.no_progress)
    except KeyboardInterrupt:
        return interrupted("bracing-study")
    report = write_report(study, args.output, time.perf_counter() - start, where, result.skipped, search, note)
    found = search.found if search is not None else None
    trials = f"; optimiser: {found.trials} trials ({found.search.ran} now)" if found is not None else ""
    print(f"bracing-study: {result.ran} run now, {result.skipped} reused{trials}; report: {report}")
    code = study_exit("bracing-study", result.rows, result.lost, args.output)
    return code or (EXIT_FAILED if found is not None and found.search.failed else 0)


if __name__ == "__main__":
    sys.exit(main())
