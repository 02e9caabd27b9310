"""The robustness study's runs (bracing-study robustness; the command and what it models: ``robustness``):
its factors and levels, the laws, the variants, and every run's spec, validated."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from bracing_core import schema
from bracing_core.config import SharedConfig
from bracing_core.numbers import number
from bracing_core.overrides import CONTROLLER, SIMULATOR, node_params, route
from bracing_core.params import ConfigError
from bracing_core.variants import BRACED, FREE_SPACE, PASSIVE, Variant
from bracing_experiments.experiment import RunSpec
from bracing_experiments.reporting import is_ok
from bracing_experiments.specs import make_spec
from bracing_experiments.study_runs import Replicas, seed_label, seed_list

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
"""The study's first seed: sensors.noise_seed of every run with noise (each run reproducible bit for bit; with
--seeds N, seeds NOISE_SEED to NOISE_SEED + N - 1)."""
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
                {"sensors.force_noise_n": s, "sensors.force_bias_n": FORCE_BIAS_N},  # seeded by Replicas
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
    runs: dict[Case, RunSpec] = field(default_factory=dict)  # the first seed's run of each case
    base: dict[str, Any] = field(default_factory=dict)  # the --set overrides of every run
    replicas: Replicas = field(default_factory=lambda: Replicas([NOISE_SEED]))  # each case's run per seed

    @property
    def specs(self) -> list[RunSpec]:
        """Every run to execute (each seed's; a run that draws no noise once)."""
        return self.replicas.specs

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
    seeds: int = 1,
) -> Robustness:
    """Every run of the study, validated (ConfigError names the parameter). ``base``: overrides of every
    run (--set); ``levels_per_factor``: keep each factor's last n levels only (a quick study); ``seeds``:
    runs per case, seeded NOISE_SEED, NOISE_SEED + 1, ... where a run draws noise."""
    base = dict(base or {})
    routed = route(base)
    params = node_params(config, routed)
    ctl = schema.read("controller", params[CONTROLLER])
    shared = SharedConfig.from_values(ctl, [config.resolve().parent])
    braced = [c for c in shared.contacts if c.brace_axes and c.desired_normal_force]
    if not braced:
        raise ConfigError("contacts.names: the study needs a bracing contact (one with brace_axes and a desired force)")
    step = float(schema.read("simulator", params[SIMULATOR]).params.step)
    factors = paper_factors(step, braced[0].friction)
    if levels_per_factor is not None:
        if levels_per_factor < 1:
            raise ConfigError("levels_per_factor must be >= 1")
        factors = tuple(replace(f, levels=f.levels[-levels_per_factor:]) for f in factors)
    mode = str(ctl.params.input_mode)
    study = Robustness(config, duration, factors, mode, [c.name for c in braced], base=base)
    study.replicas = Replicas(seed_list(NOISE_SEED, seeds))

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
        study.runs[case] = study.replicas.add(
            labels,
            lambda extra: make_spec(config, labels, duration, seed_label(extra), overrides={**overrides, **extra}),
        )

    for factor, level in study.points():
        for law in LAWS:
            for variant in VARIANTS:
                add(factor, level, law, variant, mode)
            if study.torque_rows and (factor is None or factor.torque):
                add(factor, level, law, BRACED, TORQUE)
    return study


def force_error(row: dict[str, Any] | None) -> float | None:
    """The braced force error the report compares: after the transient when the run reached it, else the
    whole run's."""
    if not is_ok(row):
        return None
    assert row is not None
    late, whole = row.get(FORCE_LATE), row.get(FORCE_RMS)
    return float(late) if number(late) else float(whole) if number(whole) else None
