"""bracing-optimize's problem: what varies (``--vary``), what is minimised and bounded, each trial's run
spec (the sweeps' ``make_spec``), all checked before any trial runs."""

from __future__ import annotations

import difflib
import hashlib
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from bracing_core import rcl_yaml, schema
from bracing_core.config import SharedConfig
from bracing_core.overrides import CONTROLLER, SIMULATOR, destination, format_value, node_params, parse_single, route
from bracing_core.params import ConfigError
from bracing_core.rollout import build_scenario
from bracing_core.schema import Kind
from bracing_experiments.experiment import STATUS_OK, RunSpec, execute_run
from bracing_experiments.specs import make_spec
from bracing_experiments.study_runs import check_window

STATUS_INFEASIBLE, STATUS_FAILED, STATUS_INTERRUPTED = "infeasible", "failed", "interrupted"
_VARY = re.compile(r"^\s*([A-Za-z_][\w.]*)(?:\[(\d+)\])?\s*=\s*([^:]+):([^:]+)$")
_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*(<=|>=)\s*(\S+)\s*$")


@dataclass(frozen=True)
class Vary:
    key: str  # the parameter (contacts.elbow.target)
    index: int | None  # its element, for a list
    low: float
    high: float
    integer: bool = False

    @property
    def name(self) -> str:
        return self.key if self.index is None else f"{self.key}[{self.index}]"

    @property
    def flag(self) -> str:
        return f"--vary {self.name}={self.low:g}:{self.high:g}"


@dataclass(frozen=True)
class Constraint:
    metric: str
    upper: bool  # METRIC <= bound (else >=)
    bound: float

    @property
    def text(self) -> str:
        return f"{self.metric}{'<=' if self.upper else '>='}{self.bound:g}"

    def violation(self, value: float) -> float:
        """<= 0 when satisfied (Optuna's convention for a constraint value)."""
        return value - self.bound if self.upper else self.bound - value


@dataclass
class Problem:
    config: Path
    varies: list[Vary]
    objectives: list[str]
    constraints: list[Constraint] = field(default_factory=list)
    duration: float | None = None
    base: dict[str, Any] = field(default_factory=dict)  # --set-style overrides of every trial
    lists: dict[str, list[float]] = field(default_factory=dict)  # a list parameter's value before its element varies

    def overrides(self, values: dict[str, float]) -> dict[str, Any]:
        """The flat parameters of a trial: the base overrides, each varied value in place (an element
        in a copy of its list). The one assembly of a trial's parameters (its spec, best.yaml)."""
        out = dict(self.base)
        for vary in self.varies:
            value = values[vary.name]
            if vary.index is None:
                out[vary.key] = value
            else:
                items = list(out.get(vary.key, self.lists[vary.key]))
                items[vary.index] = value
                out[vary.key] = items
        return out

    def spec(self, values: dict[str, float], extra: dict[str, Any] | None = None) -> RunSpec:
        """A trial's run, validated as a sweep's (ConfigError names the parameter)."""
        overrides = {**self.overrides(values), **(extra or {})}
        return make_spec(self.config, dict(values), self.duration, overrides=overrides)

    def manifest(self) -> dict[str, Any]:
        """What makes the study: a rerun must be the same problem to resume it."""
        return {
            "config": str(self.config.resolve()),
            "config_sha1": hashlib.sha1(self.config.read_bytes()).hexdigest(),
            "vary": [vary.flag for vary in self.varies],
            "minimize": self.objectives,
            "subject_to": [c.text for c in self.constraints],
            "duration": self.duration,
            "set": {key: format_value(value) for key, value in self.base.items()},
        }

    @property
    def key(self) -> str:
        """A short name of the problem (its manifest's digest): a directory per problem (the study's)."""
        return hashlib.sha1(json.dumps(self.manifest(), sort_keys=True).encode()).hexdigest()[:10]


def parse_vary(text: str) -> Vary:
    """``KEY=LOW:HIGH`` or ``KEY[i]=LOW:HIGH`` of a numeric parameter; ConfigError naming it otherwise."""
    match = _VARY.match(text)
    if not match:
        raise ConfigError(
            f"--vary {text}: expected KEY=LOW:HIGH or KEY[i]=LOW:HIGH (e.g. contacts.elbow.target[1]=0.35:0.85)"
        )
    key, index, low_text, high_text = match.groups()
    name = f"{key}[{index}]" if index is not None else key
    try:
        destination(key)
    except ConfigError as exc:
        raise ConfigError(str(exc).replace("--set ", "--vary ", 1)) from None
    kind = rcl_yaml.kind_of(key)
    if index is None and kind not in (Kind.DOUBLE, Kind.INTEGER):
        hint = " (a list: vary one element, KEY[i])" if kind is Kind.DOUBLE_ARRAY else ""
        raise ConfigError(f"--vary {name}: not a numeric parameter ({kind.value if kind else 'unknown type'}){hint}")
    if index is not None and kind is not Kind.DOUBLE_ARRAY:
        raise ConfigError(f"--vary {name}: {key} is not a list of numbers ({kind.value if kind else 'unknown type'})")
    try:
        low, high = float(low_text), float(high_text)
    except ValueError:
        raise ConfigError(f"--vary {name}: range {low_text}:{high_text} is not two numbers") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ConfigError(f"--vary {name}: range {low_text}:{high_text} needs finite LOW < HIGH")
    integer = kind is Kind.INTEGER
    if integer and (low != int(low) or high != int(high)):
        raise ConfigError(f"--vary {name}: an integer parameter needs integer bounds, got {low_text}:{high_text}")
    return Vary(key, None if index is None else int(index), low, high, integer)


def parse_constraint(text: str) -> Constraint:
    match = _CONSTRAINT.match(text)
    if not match:
        raise ConfigError(f"--subject-to {text!r}: expected 'METRIC<=VALUE' or 'METRIC>=VALUE'")
    metric, operator, bound = match.groups()
    try:
        value = float(bound)
    except ValueError:
        raise ConfigError(f"--subject-to {text!r}: {bound} is not a number") from None
    return Constraint(metric, operator == "<=", value)


def list_value(config: Path, key: str, base: dict[str, Any]) -> list[float]:
    """A list parameter as a run reads it: the override, the file's, or for an empty contact target
    the contact's start position (what ``contacts.<name>.target: []`` means)."""
    node = CONTROLLER if destination(key) in ("shared", CONTROLLER) else SIMULATOR
    value = node_params(config, base)[node].get(key, [])
    parts = key.split(".")
    if not value and len(parts) == 3 and parts[0] == "contacts" and parts[2] == "target":
        return contact_start(config, parts[1], base)
    return [float(v) for v in value]


def contact_start(config: Path, contact: str, base: dict[str, Any]) -> list[float]:
    """Where ``contact`` is at the scenario's start (as the study's placement grid reads it)."""
    routed = route(base)
    ctl = node_params(config, routed)[CONTROLLER]
    shared = SharedConfig.from_values(schema.read("controller", ctl), [config.resolve().parent])
    names = [c.name for c in shared.contacts]
    scenario = build_scenario(config, shared=routed.shared, sim=routed.simulator, with_controller=False)
    positions = scenario.sim.evaluate(np.zeros(scenario.sim.n)).positions
    if contact not in names:
        raise ConfigError(f"contacts.{contact}.target: no contact {contact!r} in the scenario")
    return [float(v) for v in positions[names.index(contact)]]


def build_problem(
    config: Path,
    vary: Sequence[str],
    minimize: Sequence[str],
    subject_to: Sequence[str] = (),
    duration: float | None = None,
    sets: Sequence[str] = (),
    base: dict[str, Any] | None = None,
) -> Problem:
    """The problem, checked before any trial: every key, range and list index; each bound of each
    range runs through the scenario's checks (make_spec: types, bounds, the task rank at the start).
    ``base``: fixed overrides already parsed (after ``sets``)."""
    if not config.is_file():
        raise ConfigError(f"--config: file not found: {config}")
    if not vary:
        raise ConfigError("--vary: at least one KEY=LOW:HIGH")
    if not minimize:
        raise ConfigError("--minimize: at least one METRIC")
    varies = [parse_vary(text) for text in vary]
    names = [v.name for v in varies]
    if len(set(names)) != len(names):
        raise ConfigError(f"--vary: a parameter given twice ({', '.join(n for n in names if names.count(n) > 1)})")
    base = {**parse_single(sets), **(base or {})}
    problem = Problem(config, varies, list(minimize), [parse_constraint(c) for c in subject_to], duration, base)
    for v in varies:
        if v.index is not None and v.key not in problem.lists:
            problem.lists[v.key] = list_value(config, v.key, base)
        if v.index is not None and v.index >= len(problem.lists[v.key]):
            length = len(problem.lists[v.key])
            raise ConfigError(f"--vary {v.name}: {v.key} has {length} value{'s' if length != 1 else ''}")
    middle = {v.name: (v.low + v.high) / 2 for v in varies}
    for v in varies:
        for bound in (v.low, v.high):
            try:
                problem.spec({**middle, v.name: bound})
            except ConfigError as exc:
                raise ConfigError(f"{v.flag}: {bound:g} is refused: {exc}") from None
    check_window(problem.spec(middle).duration, metrics=[*problem.objectives, *(c.metric for c in problem.constraints)])
    return problem


def check_metrics(problem: Problem) -> None:
    """Every objective and constraint names a column of a run's row: a probe run of a few steps."""
    probe = problem.spec({v.name: (v.low + v.high) / 2 for v in problem.varies})
    row = execute_run(replace(probe, duration=min(probe.duration, 0.01))).row
    if row.get("status") != STATUS_OK:
        return  # the trials will say why
    for flag, metric in [("--minimize", m) for m in problem.objectives] + [
        ("--subject-to", c.metric) for c in problem.constraints
    ]:
        if metric not in row:
            close = difflib.get_close_matches(metric, list(row), n=3)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise ConfigError(f"{flag} {metric}: not a metric of a run{hint}")
