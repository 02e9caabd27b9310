"""bracing-study robustness: the paper's claims on a plant that differs from the controller's model, with
real sensing and late commands, with and without force feedback (issue 34).

    bracing-study robustness --output DIR [--duration S] [--workers N | --scheduler ADDRESS] [--no-progress]
                             [--set KEY=VALUE ...]

The paper scenario (config/paper_4link.yaml), braced, passive and in free space (bracing_core.variants:
make run's three runs), one factor at a time around the nominal (the controller's model exact, exact
sensing, no latency), not a full factorial:

- model error, in the simulated plant only: link masses and inertias x 0.7-1.3 (``plant_error.mass_scale``),
  the contact's mu 0.05-0.3 (``plant_error.friction_scale``; the paper's mu is 0.1), the motors' K and R
  x 0.9 and x 1.1 (``plant_error.torque_constant_scale``, ``plant_error.resistance_scale``);
- sensing: encoders of 4096 and 1024 counts per joint revolution, velocities differentiated from them
  (``sensors.encoder_counts_per_rev``, ``sensors.velocity_filter_hz``); a force sensor with 0.5 and 2 N of
  noise and a bias (``sensors.force_noise_n``, ``sensors.force_bias_n``);
- command latency: 1, 2 and 5 steps of the scenario's (1 ms) step (``sensors.command_latency_steps``);

each level with the paper's law and with force feedback on the braced contacts
(``contacts.<name>.force_feedback.kp`` / ``.ki``) plus thermal compensation of the voltage law
(``voltage_law.thermal_compensation``); passive and free runs have no braced contact, so they take the
thermal compensation only. In the scenario's input mode (voltage), and braced in torque mode too for the
model-error factors that apply to it (masses, friction).

Writes DIR/report.md (a table and a figure per factor, the nominal, and one generated paragraph: where
bracing still pays, and what force feedback buys), DIR/robustness_<factor>.png, and the sweep's
DIR/results.parquet, DIR/results.csv and DIR/runs/ (the same command again reuses finished runs).
Exit 0 when every run is ok, 1 when one failed (the report is still written, its cells say which),
2 on a configuration error before any run (every run's configuration is checked first), 130 when
interrupted.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bracing_analysis.ratios import RATIO_FLOOR, ratio
from bracing_analysis.summary import HAND_ERROR_T_MIN_S
from bracing_core import schema
from bracing_core.config import SharedConfig
from bracing_core.numbers import markdown_table, number
from bracing_core.overrides import CONTROLLER, SIMULATOR, node_params, parse_single, route
from bracing_core.params import ConfigError
from bracing_core.variants import BRACED, FREE_SPACE, PASSIVE, Variant
from bracing_experiments.cli import (
    add_study_options,
    check_options,
    config_error,
    handle_stop_signals,
    interrupted,
    study_exit,
)
from bracing_experiments.executors import make_executor
from bracing_experiments.experiment import RunSpec
from bracing_experiments.reporting import (
    braced_forces,
    is_ok,
    resolve_scenario,
    run_arrays,
    warnings_section,
)
from bracing_experiments.sweep import ResultsStore, make_spec, run_sweep

if TYPE_CHECKING:
    from matplotlib.axes import Axes

STUDY = "robustness"
"""bracing-study's first argument for this study (study.main dispatches it here)."""
REPORT = "report.md"
ENERGY, HAND_RMS, FORCE_RMS = "energy_consumed_j", "hand_rms_error_m", "normal_force_rms_error_n"
FORCE_LATE = "normal_force_rms_error_late_n"
"""|f_n - f_nd| RMS over t >= HAND_ERROR_T_MIN_S of the braced contacts, from a run's arrays (the report's; not
a summary.json key): the summary's RMS covers the whole run, whose first second is the start's transient."""

NOMINAL = "nominal"
PAPER_LAW, FEEDBACK_LAW = "paper", "feedback"
LAWS = (PAPER_LAW, FEEDBACK_LAW)
LAW_TEXT = {PAPER_LAW: "paper's law", FEEDBACK_LAW: "force feedback + thermal comp."}
VARIANTS: tuple[Variant, ...] = (BRACED, PASSIVE, FREE_SPACE)
"""make run's three runs: their parameters (Variant.overrides) and names (Variant.name: the rows' ``variant``)."""

VOLTAGE, TORQUE = "voltage", "torque"
FEEDBACK_GAINS: dict[str, tuple[float, float]] = {VOLTAGE: (1.0, 10.0), TORQUE: (0.3, 100.0)}
"""Force feedback's (kp, ki [1/s]) by input mode, f_cmd = f_nd + kp (f_nd - f_meas) + ki * integral (f_nd -
f_meas) dt. The two inputs close different loops, so they get different gains:
- torque input: the plant passes f_cmd to f_n within the step (eq. 40) and f_meas is the previous step's
  force, so the proportional part is e_k = d - g kp e_(k-1) (d the model error's force, g ~ 1): kp must stay
  below 1 (at 1: a 2-step oscillation that never decays). kp = 0.3 takes 23 % of d at once and ki = 100 /s the
  rest, with a time constant (1 + kp) / ki = 13 ms. Measured (10 s runs, masses x 0.7-1.3 in the plant): the
  force RMS after 2 s falls from 1.9-4.0 N to 0.008-0.16 N; with kp 0.5, ki 20 to 0.02-0.22 N.
- voltage input: the force follows the command through the windings, L / R = 0.17 / 0.6 = 0.28 s (tau), so
  tau s^2 + (1 + kp) s + ki = 0: kp damps, ki speeds up. kp = 1, ki = 10 /s: 5.9 rad/s at a damping ratio of
  0.6, settled within the 2 s before the late metrics count, far from the task's 0.1 Hz and from the 1 kHz step
  (a 5 ms latency costs it 0.03 rad of phase). Measured: ki >= 50 /s (damping <= 0.16) oscillates until a
  winding burns; kp 0.5, ki 20 (damping 0.32) leaves 0.18 N at the nominal, 0.24 N at 5 ms latency, 3.6 N
  with x 1.3 masses; kp 1, ki 10 leaves 0.05, 0.07 and 2.4 N.
"""
NOISE_SEED = 1
"""sensors.noise_seed of every run with noise (each run reproducible bit for bit)."""
VELOCITY_FILTER_HZ = 50.0
"""[Hz] encoder levels: dq differentiated from the quantised q through this first-order low-pass (as a drive
does). Its lag, not the counts' ripple, is what the arm feels: measured at 4096 and 1024 counts (10 s runs),
free space draws 13-20 kJ at 50 Hz, 41 kJ at 20 Hz, 139 kJ at 10 Hz, and its windings burn at 5 Hz (at 10-20 Hz
too with thermal compensation), while the braced arm's hand RMS stays within 0.05-0.055 m from 10 Hz up."""
FORCE_BIAS_N = 0.5
"""[N] the force sensor's bias (5 % of the paper's f_nd) at both noise levels: what integral feedback on a
biased sensor converges to (f_n = f_nd - bias)."""

MASS_SCALES = (0.7, 0.85, 1.15, 1.3)
FRICTIONS = (0.05, 0.2, 0.3)  # mu; the paper's is 0.1
MOTOR_SCALES = (0.9, 1.1)
ENCODER_COUNTS = (4096, 1024)
FORCE_NOISES = (0.5, 2.0)  # [N] sigma
LATENCY_STEPS = (1, 2, 5)


@dataclass(frozen=True)
class Level:
    """One level of a factor: its parameters (beside the nominal scenario's)."""

    label: str  # in the tables and the paragraph, self-contained: "masses x1.3", "latency 5 ms"
    value: float  # on the figure's x axis
    overrides: Mapping[str, Any]


@dataclass(frozen=True)
class Factor:
    key: str  # its rows' ``factor`` and its figure's name
    title: str
    models: str  # what it models, one sentence
    axis: str  # the figure's x axis
    nominal: float  # the nominal's place on that axis
    levels: tuple[Level, ...]
    torque: bool = False  # braced torque-input rows too (a model error that applies to direct drive)


def _mass_factor() -> Factor:
    return Factor(
        "mass",
        "Link masses and inertias",
        "Every link's mass and rotational inertia in the plant times the scale; the controller keeps the file's",
        "mass scale (plant / model)",
        1.0,
        tuple(Level(f"masses x{s:g}", s, {"plant_error.mass_scale": s}) for s in MASS_SCALES),
        torque=True,
    )


def _friction_factor(mu: float) -> Factor:
    return Factor(
        "friction",
        "Contact friction",
        f"The contact's mu in the plant (the model's: {mu:g})",
        "mu (plant)",
        mu,
        tuple(Level(f"mu {m:g}", m, {"plant_error.friction_scale": m / mu}) for m in FRICTIONS),
        torque=True,
    )


def _motor_factors() -> tuple[Factor, Factor]:
    """The torque constant and the winding resistance, each scaled in the plant."""
    return (
        Factor(
            "torque_constant",
            "Motor torque constant",
            "Every motor's K (torque and back-EMF constant) in the plant times the scale",
            "K scale (plant / model)",
            1.0,
            tuple(Level(f"K x{s:g}", s, {"plant_error.torque_constant_scale": s}) for s in MOTOR_SCALES),
        ),
        Factor(
            "resistance",
            "Winding resistance",
            "Every motor's R at 20 degC in the plant times the scale",
            "R scale (plant / model)",
            1.0,
            tuple(Level(f"R x{s:g}", s, {"plant_error.resistance_scale": s}) for s in MOTOR_SCALES),
        ),
    )


def _encoder_factor() -> Factor:
    return Factor(
        "encoder",
        "Encoders",
        "The joint positions q published on a grid of 2 pi / counts per joint revolution, dq differentiated "
        f"from them through a {VELOCITY_FILTER_HZ:g} Hz first-order low-pass",
        "encoder count [mrad]",
        0.0,
        tuple(
            Level(
                f"{n} counts/rev",
                2 * math.pi / n * 1e3,
                {"sensors.encoder_counts_per_rev": n, "sensors.velocity_filter_hz": VELOCITY_FILTER_HZ},
            )
            for n in ENCODER_COUNTS
        ),
    )


def _force_sensor_factor() -> Factor:
    seeded = {"sensors.noise_seed": NOISE_SEED}
    return Factor(
        "force_sensor",
        "Force sensor",
        f"White noise of the given sigma on each force component of contact_wrench/<contact>, plus a "
        f"{FORCE_BIAS_N:g} N bias along the normal (only force feedback reads it)",
        "force noise sigma [N]",
        0.0,
        tuple(
            Level(
                f"force noise {s:g} N, bias {FORCE_BIAS_N:g} N",
                s,
                {**seeded, "sensors.force_noise_n": s, "sensors.force_bias_n": FORCE_BIAS_N},
            )
            for s in FORCE_NOISES
        ),
    )


def _latency_factor(step: float) -> Factor:
    return Factor(
        "latency",
        "Command latency",
        f"Each command applied k steps ({step * 1e3:g} ms each) after the state it answers",
        "latency [ms]",
        0.0,
        tuple(
            Level(f"latency {k * step * 1e3:g} ms", k * step * 1e3, {"sensors.command_latency_steps": k})
            for k in LATENCY_STEPS
        ),
    )


def paper_factors(step: float, mu: float) -> tuple[Factor, ...]:
    """The study's factors and levels for a scenario with step ``step`` [s] whose braced contact has ``mu``."""
    if mu <= 0:
        raise ConfigError("the robustness study scales the braced contact's friction: it needs mu > 0")
    return (
        _mass_factor(),
        _friction_factor(mu),
        *_motor_factors(),
        _encoder_factor(),
        _force_sensor_factor(),
        _latency_factor(step),
    )


NOMINAL_LEVEL = Level(NOMINAL, math.nan, {})


@dataclass(frozen=True)
class Case:
    """Where a run sits in the study: (factor, level, law, variant, input mode)."""

    factor: str
    level: str
    law: str
    variant: str
    mode: str


@dataclass
class Robustness:
    """Every run of the study, by where it sits (``runs``), and what the report needs to place them."""

    config: Path
    duration: float | None
    factors: tuple[Factor, ...]
    mode: str  # the file's input mode (with --set)
    braced: list[str]  # the braced contacts' names
    runs: dict[Case, RunSpec] = field(default_factory=dict)
    base: dict[str, Any] = field(default_factory=dict)  # the --set overrides of every run

    @property
    def specs(self) -> list[RunSpec]:
        return list(self.runs.values())

    @property
    def scenario(self) -> str:
        return self.config.stem

    @property
    def torque_rows(self) -> bool:
        """Braced torque-input rows beside the file's mode (only when that is voltage)."""
        return self.mode == VOLTAGE

    def points(self) -> list[tuple[Factor | None, Level]]:
        """The nominal (factor None) and every factor's levels, in report order."""
        return [(None, NOMINAL_LEVEL), *((f, level) for f in self.factors for level in f.levels)]

    def case(self, factor: Factor | None, level: Level, law: str, variant: str, mode: str | None = None) -> Case:
        return Case(factor.key if factor else NOMINAL, level.label, law, variant, mode or self.mode)

    def spec(self, factor: Factor | None, level: Level, law: str, variant: str, mode: str | None = None) -> RunSpec:
        return self.runs[self.case(factor, level, law, variant, mode)]

    def row(
        self,
        rows: Mapping[str, dict[str, Any]],
        factor: Factor | None,
        level: Level,
        law: str,
        variant: str,
        mode: str | None = None,
    ) -> dict[str, Any] | None:
        """That run's row in ``rows`` (by run id), or None (not run, or no such run)."""
        spec = self.runs.get(self.case(factor, level, law, variant, mode))
        return rows.get(spec.run_id) if spec is not None else None


def _gains(mode: str) -> str:
    kp, ki = FEEDBACK_GAINS[mode]
    return f"kp {kp:g}, ki {ki:g} /s"


def law_overrides(law: str, variant: Variant, mode: str, braced: Sequence[str]) -> dict[str, Any]:
    """The parameters of ``law``: nothing for the paper's; force feedback on the braced contacts (a run with
    a brace task only) and thermal compensation (voltage input only: the law it compensates)."""
    if law == PAPER_LAW:
        return {}
    out: dict[str, Any] = {}
    if variant.bracing:
        kp, ki = FEEDBACK_GAINS[mode]
        for name in braced:
            out[f"contacts.{name}.force_feedback.kp"] = kp
            out[f"contacts.{name}.force_feedback.ki"] = ki
    if mode == VOLTAGE:
        out["voltage_law.thermal_compensation"] = True
    return out


def build_robustness(
    config: Path,
    duration: float | None = None,
    base: dict[str, Any] | None = None,
    levels_per_factor: int | None = None,
) -> Robustness:
    """Every run of the study, validated (ConfigError names the parameter). ``base``: overrides of every
    run (--set); ``levels_per_factor``: keep each factor's last n levels only (a quick study)."""
    base = dict(base or {})
    routed = route(base)
    params = node_params(config, routed)
    ctl = schema.read("controller", params[CONTROLLER])
    shared = SharedConfig.from_values(ctl, [config.resolve().parent])
    braced = [c for c in shared.contacts if c.brace_axes and c.desired_normal_force]
    if not braced:
        raise ConfigError("contacts.names: the study needs a bracing contact (one with brace_axes and a desired force)")
    step = float(schema.read("simulator", params[SIMULATOR])["step"])
    factors = paper_factors(step, braced[0].friction)
    if levels_per_factor is not None:
        if levels_per_factor < 1:
            raise ConfigError("levels_per_factor must be >= 1")
        factors = tuple(replace(f, levels=f.levels[-levels_per_factor:]) for f in factors)
    mode = str(ctl["input_mode"])
    study = Robustness(config, duration, factors, mode, [c.name for c in braced], base=base)

    def add(factor: Factor | None, level: Level, law: str, variant: Variant, input_mode: str) -> None:
        labels = {  # in the run id's readable part (its first 80 characters) in this order
            "factor": factor.key if factor else NOMINAL,
            "level": level.label,
            "law": law,
            "variant": variant.name,
            "input_mode": input_mode,
            "level_value": None if factor is None else level.value,
            "comparison": STUDY,
        }
        overrides = {
            **base,
            **({} if input_mode == study.mode else {"input_mode": input_mode}),
            **variant.overrides(),
            **level.overrides,
            **law_overrides(law, variant, input_mode, study.braced),
        }
        case = study.case(factor, level, law, variant.name, input_mode)
        study.runs[case] = make_spec(config, labels, duration, overrides=overrides)

    for factor, level in study.points():
        for law in LAWS:
            for variant in VARIANTS:
                add(factor, level, law, variant, mode)
            if study.torque_rows and (factor is None or factor.torque):
                add(factor, level, law, BRACED, TORQUE)
    return study


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


def _rows(study: Robustness, store: ResultsStore) -> dict[str, dict[str, Any]]:
    """Every finished run's row, by run id, the braced runs' late force RMS added."""
    rows: dict[str, dict[str, Any]] = {}
    for case, spec in study.runs.items():
        row = store.row(spec.run_id)
        if row is None:
            continue
        if case.variant == BRACED.name:
            row[FORCE_LATE] = late_force_rms(store, row)
        rows[spec.run_id] = row
    return rows


def _force(row: dict[str, Any] | None) -> float | None:
    """The braced force error the report compares: after the transient when the run reached it, else the
    whole run's."""
    if not is_ok(row):
        return None
    assert row is not None
    late, whole = row.get(FORCE_LATE), row.get(FORCE_RMS)
    return float(late) if number(late) else float(whole) if number(whole) else None


def _value(row: dict[str, Any] | None, key: str) -> Any:
    if row is None:
        return "not run"
    if not is_ok(row):
        return "failed"
    return row.get(key)


def _ratio(key: str, row: dict[str, Any] | None, baseline: dict[str, Any] | None) -> float | None:
    if not (is_ok(row) and is_ok(baseline)):
        return None
    assert row is not None and baseline is not None
    return ratio(key, row, baseline)[0]


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
        _ratio(ENERGY, braced, free),
        _ratio(HAND_RMS, braced, free),
        _ratio(ENERGY, braced, passive),
        _ratio(HAND_RMS, braced, passive),
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
    _draw_factor(study, store, rows, factor, figure)
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


_LAW_COLOURS = {PAPER_LAW: "tab:blue", FEEDBACK_LAW: "tab:orange"}
_VARIANT_STYLES = {BRACED.name: "-", PASSIVE.name: ":", FREE_SPACE.name: "--"}
_Points = list[tuple[float, Factor | None, Level]]  # (x, factor or None for the nominal, level), by x


def _series(
    study: Robustness,
    rows: Mapping[str, dict[str, Any]],
    points: _Points,
    law: str,
    variant: str,
    get: Any,
    mode: str | None = None,
) -> list[float]:
    """``get`` of that run's row at each point; nan where it is not a number."""
    values = []
    for _, where, level in points:
        value = get(study.row(rows, where, level, law, variant, mode))
        values.append(float(value) if number(value) else math.nan)
    return values


def _plot_hand(ax: Axes, study: Robustness, rows: Mapping[str, dict[str, Any]], points: _Points, law: str) -> None:
    xs = [p[0] for p in points]
    for variant in VARIANTS:
        hand = _series(study, rows, points, law, variant.name, lambda r: r.get(HAND_RMS) if is_ok(r) else None)
        ax.plot(
            xs,
            hand,
            marker="o",
            ls=_VARIANT_STYLES[variant.name],
            color=_LAW_COLOURS[law],
            label=f"{variant.column}, {LAW_TEXT[law]}",
        )


def _plot_force(
    ax: Axes, study: Robustness, rows: Mapping[str, dict[str, Any]], points: _Points, law: str, factor: Factor
) -> bool:
    """The braced force error in the file's mode (and torque input's, when the study has those rows);
    True when a value is finite (a log axis can draw it)."""
    xs = [p[0] for p in points]
    force = _series(study, rows, points, law, BRACED.name, _force)
    finite = bool(np.isfinite(force).any())
    ax.plot(
        xs, [max(v, 1e-15) for v in force], marker="o", color=_LAW_COLOURS[law], label=f"{study.mode}, {LAW_TEXT[law]}"
    )
    if study.torque_rows and factor.torque:
        torque = _series(study, rows, points, law, BRACED.name, _force, TORQUE)
        finite = finite or bool(np.isfinite(torque).any())
        ax.plot(
            xs,
            [max(v, 1e-15) for v in torque],
            marker="s",
            ls="--",
            color=_LAW_COLOURS[law],
            alpha=0.7,
            label=f"torque, {'force feedback' if law == FEEDBACK_LAW else LAW_TEXT[law]}",
        )
    return finite


def _plot_energy_ratios(
    ax: Axes, study: Robustness, rows: Mapping[str, dict[str, Any]], points: _Points, law: str
) -> None:
    """Braced energy over free space's and over resting passively's."""
    xs = [p[0] for p in points]
    for baseline, marker in ((FREE_SPACE, "o"), (PASSIVE, "^")):
        values = []
        for _, where, level in points:
            braced = study.row(rows, where, level, law, BRACED.name)
            other = study.row(rows, where, level, law, baseline.name)
            value = _ratio(ENERGY, braced, other)
            values.append(value if value is not None else math.nan)
        ax.plot(
            xs,
            values,
            marker=marker,
            ls=_VARIANT_STYLES[baseline.name],
            color=_LAW_COLOURS[law],
            label=f"braced / {baseline.column}, {LAW_TEXT[law]}",
        )


def _draw_factor(
    study: Robustness, store: ResultsStore, rows: Mapping[str, dict[str, Any]], factor: Factor, name: str
) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    points = sorted(
        [(factor.nominal, None, NOMINAL_LEVEL), *((lv.value, factor, lv) for lv in factor.levels)], key=lambda p: p[0]
    )
    fig = Figure(figsize=(14, 4.2), layout="constrained")
    fig.suptitle(f"{study.scenario}: {factor.title.lower()} ({study.mode} input unless marked)")
    hand_ax, force_ax, ratio_ax = fig.subplots(1, 3)
    logarithmic = False
    for law in LAWS:
        _plot_hand(hand_ax, study, rows, points, law)
        finite = _plot_force(force_ax, study, rows, points, law, factor)
        logarithmic = logarithmic or finite
        _plot_energy_ratios(ratio_ax, study, rows, points, law)
    ratio_ax.axhline(1.0, color="grey", lw=1.0)
    for ax in (hand_ax, force_ax, ratio_ax):
        ax.axvline(factor.nominal, color="grey", ls=":", lw=0.8)
        ax.set_xlabel(factor.axis)
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=6)
    hand_ax.set(title=f"hand RMS error (t >= {HAND_ERROR_T_MIN_S:g} s)", ylabel="[m]")
    force_ax.set(title=f"braced |f_n - f_nd| RMS (t >= {HAND_ERROR_T_MIN_S:g} s if run so long)", ylabel="[N]")
    if logarithmic:  # (a log axis without a finite value refuses to draw)
        force_ax.set_yscale("log")  # torque input's is ~1e-14 N where the model is exact
    ratio_ax.set(title="energy ratio of bracing (< 1: bracing saves)", ylabel="ratio")
    fig.savefig(store.output / name, dpi=110)


def _span(values: Sequence[float]) -> str:
    lo, hi = min(values), max(values)
    return f"x{lo:.3g}" if f"{lo:.3g}" == f"{hi:.3g}" else f"x{lo:.3g}-{hi:.3g}"


def _listed(items: Sequence[str], most: int = 4) -> str:
    shown = list(items[:most]) + ([f"{len(items) - most} more"] if len(items) > most else [])
    return shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " and " + shown[-1]


def _named(level: Level) -> str:
    """A level in a sentence."""
    return "the nominal" if level is NOMINAL_LEVEL else level.label


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
    for law in LAWS:
        law_text = "the paper's law" if law == PAPER_LAW else "feedback"
        for factor, level in study.points():
            braced = study.row(rows, factor, level, law, BRACED.name)
            other = study.row(rows, factor, level, law, baseline.name)
            energy, hand = _ratio(ENERGY, braced, other), _ratio(HAND_RMS, braced, other)
            if energy is None:
                continue
            judged[law] += 1
            energies.append(energy)
            if hand is not None:
                hands.append(hand)
            where = f"{_named(level)} with {law_text}"
            if energy < 1 and (hand is None or hand < 1):
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
    against = "free space" if baseline is FREE_SPACE else "resting passively"
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


def _buys(study: Robustness, rows: Mapping[str, dict[str, Any]]) -> str:
    """What force feedback + thermal compensation changes in the braced runs: the force error, the hand RMS,
    the energy; with torque input, under the model error that hurts most."""
    nominal_paper = study.row(rows, None, NOMINAL_LEVEL, PAPER_LAW, BRACED.name)
    nominal_feedback = study.row(rows, None, NOMINAL_LEVEL, FEEDBACK_LAW, BRACED.name)
    late = is_ok(nominal_paper) and number((nominal_paper or {}).get(FORCE_LATE))
    when = f"after {HAND_ERROR_T_MIN_S:g} s" if late else "over the run"
    forces: list[tuple[float, str, float, float]] = []  # (feedback / paper, level, paper, feedback)
    hands: list[float] = []
    energies: list[float] = []
    for factor, level in study.points():
        paper = study.row(rows, factor, level, PAPER_LAW, BRACED.name)
        feedback = study.row(rows, factor, level, FEEDBACK_LAW, BRACED.name)
        before, after = _force(paper), _force(feedback)
        if before is not None and after is not None and before >= RATIO_FLOOR:
            forces.append((after / before, _named(level), before, after))
        for key, out in ((HAND_RMS, hands), (ENERGY, energies)):
            value = _ratio(key, feedback, paper)
            if value is not None:
                out.append(value)
    if not forces:
        return ""
    text = f"force feedback ({_gains(study.mode)}) with thermal compensation"
    start = _force(nominal_paper), _force(nominal_feedback)
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
        paper = _force(study.row(rows, factor, level, PAPER_LAW, BRACED.name, TORQUE))
        feedback = _force(study.row(rows, factor, level, FEEDBACK_LAW, BRACED.name, TORQUE))
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
    rows = _rows(study, store)
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
        f"lockstep); {ok} ok, {len(rows) - ok} failed{'' if len(rows) == len(study.specs) else ', the rest not run'}. "
        f"{compute:.0f} s of run time in all; this report's invocation took {wall_time_s:.0f} s on {executor}"
        f"{f' ({reused} runs reused)' if reused else ''}. Every run's row: `results.csv` / `results.parquet`; its "
        "summary and arrays: `runs/<run id>/`.",
        "",
        f"The paper's task braced, {PASSIVE.label} and in {FREE_SPACE.label}, {study.mode} input, one factor "
        "at a time around the nominal (the controller's model exact, exact sensing, no latency): each level with "
        f"the paper's law and with force feedback on the braced contact {contacts} (f_cmd = f_nd + kp (f_nd - "
        f"f_meas) + ki * integral, {gains}) plus thermal compensation of the voltage law; passive and free runs "
        f"have no brace task, so they take the thermal compensation only.{torque} Hand RMS over t >= "
        f"{HAND_ERROR_T_MIN_S:g} s; the braced contact's |f_n - f_nd| RMS over the whole run (summary.json's) and "
        f"after {HAND_ERROR_T_MIN_S:g} s (from the run's arrays); a ratio is n/a across input modes and to a "
        "baseline of ~0. Each factor's table starts with the nominal.",
        "",
        "**Where does bracing still pay, and what does force feedback buy?** "
        + (said or "No run came back ok: no answer."),
        "",
    ]
    for k, factor in enumerate(study.factors, 1):
        lines += _factor_section(study, store, rows, k, factor)
    lines += _failures_section(rows)
    lines += warnings_section(dict(rows))
    path = output / REPORT
    path.write_text("\n".join(lines))
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


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog=f"bracing-study {STUDY}", description=(__doc__ or "").split("\n\n")[0].replace("\n", " ")
    )
    add_study_options(parser, exclusive_executors=True)
    args = parser.parse_args(argv)
    check_options(parser, args)
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    handle_stop_signals()
    start = time.perf_counter()
    name = f"bracing-study {STUDY}"
    try:
        config = resolve_scenario("paper")
        study = build_robustness(config, args.duration, parse_single(args.sets))
        ResultsStore(args.output).check_manifest(config)
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        return config_error(name, exc)
    try:
        with executor:
            where = executor.description
            print(f"{name}: {len(study.specs)} runs of {config} on {where}", file=sys.stderr)
            result = run_sweep(study.specs, args.output, executor, progress=not args.no_progress)
    except KeyboardInterrupt:
        return interrupted(name)
    report = write_report(study, args.output, time.perf_counter() - start, where, result.skipped)
    print(f"{name}: {result.ran} run now, {result.skipped} reused; report: {report}")
    return study_exit(name, result.rows, result.lost, args.output)


if __name__ == "__main__":
    sys.exit(main())
