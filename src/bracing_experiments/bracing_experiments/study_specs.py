"""The paper study's runs (bracing-study paper; the command and what it compares: ``study``): the three
comparisons' specs, validated, and the optimiser's search over the placement grid's axes."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bracing_core import schema
from bracing_core.config import SharedConfig
from bracing_core.contact_config import ContactConfig
from bracing_core.numbers import number
from bracing_core.overrides import CONTROLLER, SIMULATOR, NodeOverrides, node_params, route
from bracing_core.params import ConfigError
from bracing_core.rollout import build_scenario
from bracing_core.variants import PASSIVE
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import RunSpec
from bracing_experiments.optimize_search import Optimum, optimize
from bracing_experiments.optimize_specs import Problem, build_problem
from bracing_experiments.reporting import is_ok as _ok
from bracing_experiments.specs import make_spec
from bracing_experiments.study_runs import Replicas, seed_label, seed_list

if TYPE_CHECKING:
    pass

PAPER_SCENARIO = "paper_4link"
"""The scenario whose figures the paper has: only its report cites them."""
GAIN_SCALES = (1.0, 0.5, 0.2, 0.1)
FORCE_SCALES = (0.5, 1.0, 2.0)  # x the file's desired normal force
REPORT = "report.md"
ENERGY, HAND_RMS, HAND_MAX = "energy_consumed_j", "hand_rms_error_m", "hand_max_error_m"
PAPER_SEARCH = ((0.0, 40.0), (0.35, 0.85))
"""The paper arm's search: f_nd [N] and the elbow target's y [m]."""
PAPER_HAND_RMS_BOUND = 0.03
"""[m] the paper arm's precision bound on the optimum: hand RMS <= 30 mm."""
SEARCH_WIDEN = 5 / 3
"""Other scenarios: the target's search range is the grid's (start +- span) widened by this (the
paper's 0.35-0.85 m is its start 0.588 m +- 0.25 m, 5/3 of the grid's 0.15 m), the force's 0 to
twice the grid's largest (the paper's 0-40 N)."""
SEARCH_DIR = "optimize"
SEARCH_TRIALS = 40
"""--trials' default: the paper study's search beats the grid's best in it (README: what it finds)."""
SEARCH_SEED = 0
"""The search's sampler seed when the study has none of its own (``PlacementSearch.seed``: its first seed)."""


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
    replicas: Replicas = field(default_factory=lambda: Replicas([0]))  # each condition's run per seed

    @property
    def specs(self) -> list[RunSpec]:
        """Every run to execute (each seed's; a run that draws no noise once)."""
        return self.replicas.specs

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
    start = scenario.sim.evaluate(np.zeros(scenario.sim.n)).positions
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
    seeds: int = 1,
) -> Study:
    """Every run of the three comparisons, validated. ``base``: overrides applied to all runs; ``seeds``: runs
    per condition, seeded from the scenario's sensors.noise_seed on where a run draws noise (study_runs)."""
    base = dict(base or {})
    routed = route(base)
    params = node_params(config, routed)
    ctl = params[CONTROLLER]
    first_seed = int(schema.read("simulator", params[SIMULATOR]).params.sensors.noise_seed)
    replicas = Replicas(seed_list(first_seed, seeds))
    shared = SharedConfig.from_values(schema.read("controller", ctl), [config.resolve().parent])
    braced = [c for c in shared.contacts if c.brace_axes and c.desired_normal_force]
    if not braced:
        raise ConfigError("contacts.names: the study needs a bracing contact (one with brace_axes and a desired force)")

    def spec(comparison: str, labels: dict[str, Any], overrides: dict[str, Any]) -> RunSpec:
        varied = {"comparison": comparison, **labels}
        return replicas.add(
            varied,
            lambda extra: make_spec(
                config, varied, duration, seed_label(extra), overrides={**base, **overrides, **extra}
            ),
        )

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
        setting=(str(values.params.input_mode), bool(values.params.gravity_compensation)),
        origin=float(origin[axis]),
        desired=float(desired),
        span=float(span) if positions > 1 else 0.0,
        replicas=replicas,
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
    seed: int = SEARCH_SEED  # its sampler's: the study's first seed
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
    search.seed = study.replicas.seeds[0]
    return search


def run_placement_search(
    search: PlacementSearch, executor: Executor, trials: int, progress: bool = True, seed: int | None = None
) -> PlacementSearch:
    """Resume or start the search's study (bracing-optimize's, in ``search.output``) up to ``trials``
    on ``executor``, its sampler seeded ``seed`` (default: ``search.seed``); a finished study runs nothing again."""
    search.found = optimize(
        search.problem,
        search.output,
        executor,
        trials,
        progress=progress,
        seed=search.seed if seed is None else seed,
        references=False,  # the study has the file's setting, passive and free runs itself
        first=[search.start] if search.start else [],
    )
    return search
