"""bracing-study pays's runs: the grid over f_nd and the brace place, braced, passive and in free space, in
realistic conditions drawn per seed, and the optimiser's problem over the same axes."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bracing_core import schema
from bracing_core.config import SharedConfig
from bracing_core.overrides import CONTROLLER, node_params, route
from bracing_core.params import ConfigError
from bracing_core.variants import FREE_SPACE, PASSIVE
from bracing_experiments.experiment import RunSpec
from bracing_experiments.optimize_search import Optimum
from bracing_experiments.optimize_specs import Problem, build_problem
from bracing_experiments.robustness_specs import FORCE_BIAS_N, VELOCITY_FILTER_HZ
from bracing_experiments.specs import make_spec
from bracing_experiments.study_runs import check_window, seed_list
from bracing_experiments.study_specs import _brace_origin as brace_origin

STUDY = "pays"
"""bracing-study's first argument for this study (study.main dispatches it here)."""
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
