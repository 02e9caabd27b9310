"""bracing-optimize: the scenario parameters that minimise a metric, found by Optuna on the sweeps' executors.

    bracing-optimize --config F --vary KEY=LOW:HIGH [--vary ...] --minimize METRIC [--minimize METRIC]
                     [--subject-to 'METRIC<=V' ...] [--trials N] [--workers N | --scheduler ADDRESS]
                     [--duration S] --output DIR

KEY is a numeric scenario parameter as ``--set`` spells it, ``KEY[i]`` an element of a list
(``contacts.elbow.target[1]``: the brace target's y; an empty target list is the contact's start
position, as a run reads it). METRIC is a column of a sweep's table (a summary.json key, dotted for a
contact's: ``contacts.elbow.slip_m``). One objective: Optuna's TPE sampler; two or more: NSGA-II; both
with the constraints (``METRIC<=V`` or ``METRIC>=V``) as each trial's constraint values
(``Trial.set_constraint``, which both samplers read). Each trial is one
in-process run (``bracing_experiments.experiment.execute_run``) built by the sweeps' ``make_spec``, on
local worker processes or a Dask cluster, ``workers`` trials at a time.

DIR/study.db is the Optuna study (SQLite): the same command again resumes it up to N trials; Ctrl-C
keeps every finished trial. A failing run is a failed trial (its error in the table), a run off the
constraints an infeasible one; neither stops the search. Writes DIR/trials.csv and .parquet (every
trial), DIR/best.yaml (the scenario file with the optimum filled in: ``bracing-pair --config
DIR/best.yaml`` runs it as is), DIR/report.md with convergence.png (and pareto.png with two objectives).
Exit 0 when every trial ran, 1 when one failed, 2 on a configuration error before any trial, 130 when
interrupted.
"""

from __future__ import annotations

import argparse
import difflib
import hashlib
import json
import math
import re
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm import tqdm

from bracing_core import rcl_yaml, schema
from bracing_core.config import SharedConfig
from bracing_core.numbers import cell, markdown_table, number
from bracing_core.overrides import CONTROLLER, SIMULATOR, destination, format_value, node_params, parse_single, route
from bracing_core.params import ConfigError
from bracing_core.rollout import build_scenario
from bracing_core.schema import Kind
from bracing_core.variants import BRACED, FREE_SPACE, PASSIVE
from bracing_experiments.cli import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    add_duration,
    add_executor,
    add_output,
    add_overrides,
    add_progress,
    check_options,
    config_error,
    handle_stop_signals,
)
from bracing_experiments.executors import Executor, make_executor
from bracing_experiments.experiment import STATUS_OK, RunSpec, execute_run
from bracing_experiments.optimize_record import record_optimisation
from bracing_experiments.study_runs import check_window
from bracing_experiments.sweep import make_spec
from bracing_experiments.sweep import write_tables as write_sweep_tables

if TYPE_CHECKING:
    import optuna

STUDY_DB, STUDY_NAME, MANIFEST = "study.db", "bracing-optimize", "optimize.json"
TRIALS_PARQUET, TRIALS_CSV, BEST_YAML, REPORT = "trials.parquet", "trials.csv", "best.yaml", "report.md"
REFERENCES_FILE = "references.json"
STATUS_INFEASIBLE, STATUS_FAILED, STATUS_INTERRUPTED = "infeasible", "failed", "interrupted"
REFERENCES = {  # the file's setting and make run's two other runs (variants.RUNS), marked on the figures
    "file's setting": BRACED.overrides(),
    "passive": PASSIVE.overrides(),
    "free space": FREE_SPACE.overrides(),
}
_VARY = re.compile(r"^\s*([A-Za-z_][\w.]*)(?:\[(\d+)\])?\s*=\s*([^:]+):([^:]+)$")
_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*(<=|>=)\s*(\S+)\s*$")


# -- the problem: what varies, what is minimised, what is bounded ------------------------------------------
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
    positions = scenario.sim.evaluate(np.zeros(scenario.sim.n)).contacts.positions
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


# -- the search ---------------------------------------------------------------------------------------------
def open_study(problem: Problem, output: Path, seed: int | None = None) -> optuna.Study:
    """The study in DIR/study.db (created, or loaded to resume). One objective: TPE; more: NSGA-II;
    the constraints set on each trial (_record). A resumed search seeds its sampler past the trials it
    has, so that its random start does not propose the same points again."""
    import optuna  # imported where used: optuna ~170 ms (python -X importtime)

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    output.mkdir(parents=True, exist_ok=True)
    storage = f"sqlite:///{(output / STUDY_DB).resolve()}"
    names = optuna.get_all_study_names(storage) if (output / STUDY_DB).is_file() else []
    done = len(optuna.load_study(study_name=STUDY_NAME, storage=storage).trials) if STUDY_NAME in names else 0
    shift = None if seed is None else seed + done
    sampler: optuna.samplers.BaseSampler
    if len(problem.objectives) > 1:
        sampler = optuna.samplers.NSGAIISampler(seed=shift)
    else:
        sampler = optuna.samplers.TPESampler(seed=shift, multivariate=True)
    return optuna.create_study(
        study_name=STUDY_NAME,
        storage=storage,
        sampler=sampler,
        directions=["minimize"] * len(problem.objectives),
        load_if_exists=True,
    )


def check_manifest(problem: Problem, output: Path) -> None:
    """DIR holds one problem's study: another --vary, objective, constraint or file is refused."""
    path = output / MANIFEST
    current = problem.manifest()
    if path.is_file():
        previous = json.loads(path.read_text())
        changed = [key for key in current if previous.get(key) != current[key]]
        if changed:
            raise ConfigError(
                f"--output {output}: holds a study of another problem ({', '.join(changed)} differ); "
                "choose a new output directory"
            )
    output.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(current, indent=2) + "\n")


def counted(trial: optuna.trial.FrozenTrial) -> bool:
    """A trial whose run came back (ok, infeasible or failed); an interrupted one is not."""
    return "status" in trial.user_attrs


def _distribution(vary: Vary) -> Any:
    import optuna  # imported where used: optuna ~170 ms (python -X importtime)

    if vary.integer:
        return optuna.distributions.IntDistribution(int(vary.low), int(vary.high))
    return optuna.distributions.FloatDistribution(vary.low, vary.high)


@contextmanager
def _ctrl_c_after() -> Iterator[None]:
    """Ctrl-C (SIGINT) inside waits until the block is done, then raises KeyboardInterrupt: a trial's
    record (its status, then its values) is written whole. Measured: a Ctrl-C between the two left a
    trial with a status and no values, and the outputs written on the way out failed on it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: pending.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if pending:
        raise KeyboardInterrupt


def _record(study: optuna.Study, trial: optuna.Trial, problem: Problem, row: dict[str, Any]) -> str:
    """Tell the study a trial's outcome, whole even under Ctrl-C (``_tell``)."""
    with _ctrl_c_after():
        return _tell(study, trial, problem, row)


def _tell(study: optuna.Study, trial: optuna.Trial, problem: Problem, row: dict[str, Any]) -> str:
    """Tell the study a trial's outcome; its row (every metric) kept as a user attribute."""
    from optuna.trial import TrialState  # imported where used: optuna ~170 ms (python -X importtime)

    row = {key: value for key, value in row.items() if key != "traceback"}
    trial.set_user_attr("row", row)
    values = [row.get(metric) for metric in problem.objectives]
    bounded = [row.get(c.metric) for c in problem.constraints]
    if row.get("status") != STATUS_OK:
        status = STATUS_FAILED
    elif not all(number(v) for v in [*values, *bounded]):
        status = STATUS_FAILED
        missing = [
            m
            for m, v in zip(
                [*problem.objectives, *(c.metric for c in problem.constraints)], [*values, *bounded], strict=True
            )
            if not number(v)
        ]
        trial.set_user_attr("error", f"metric not applicable or not finite: {', '.join(missing)}")
    else:
        violations = [c.violation(float(v)) for c, v in zip(problem.constraints, bounded, strict=True)]  # type: ignore[arg-type]
        trial.set_user_attr("constraints", violations)
        for constraint, violation in zip(problem.constraints, violations, strict=True):
            trial.set_constraint(constraint.text, violation)  # what the samplers read (Optuna >= 5)
        status = STATUS_INFEASIBLE if any(v > 0 for v in violations) else STATUS_OK
    trial.set_user_attr("status", status)
    if status == STATUS_FAILED:
        trial.set_user_attr("error", trial.user_attrs.get("error") or row.get("error"))
        study.tell(trial, state=TrialState.FAIL)
    else:
        study.tell(trial, [float(v) for v in values])  # type: ignore[arg-type]
    return status


@dataclass
class SearchResult:
    ran: int = 0
    failed: int = 0
    interrupted: bool = False
    wall_time_s: float = 0.0


def search(
    problem: Problem,
    study: optuna.Study,
    executor: Executor,
    trials: int,
    progress: bool = True,
    on_trial: Callable[[int, str], None] | None = None,
    first: Sequence[dict[str, float]] = (),
) -> SearchResult:
    """Run trials until the study has ``trials`` that came back: ``executor.workers`` at a time (asked
    together, told as each run returns). Ctrl-C cancels the running ones (recorded as interrupted, not
    counted) and re-raises KeyboardInterrupt with the finished ones in the study. ``first``: points
    (varied name -> value) a new study tries first, before its sampler's own (a known good setting)."""
    from optuna.trial import TrialState  # imported where used: optuna ~170 ms (python -X importtime)

    start = time.perf_counter()
    result = SearchResult()
    for stale in study.get_trials(deepcopy=False, states=(TrialState.RUNNING, TrialState.WAITING)):
        study.tell(stale.number, state=TrialState.FAIL)  # a run killed before it came back: not counted
    done = sum(1 for t in study.get_trials(deepcopy=False) if counted(t))
    if done == 0:
        for point in first:
            study.enqueue_trial(dict(point), skip_if_exists=True)
    distributions = {vary.name: _distribution(vary) for vary in problem.varies}
    bar = tqdm(
        total=trials, initial=min(done, trials), unit="trial", desc="optimize", disable=not progress, dynamic_ncols=True
    )
    pending: dict[int, Any] = {}
    try:
        while done < trials:
            batch = [study.ask(distributions) for _ in range(min(executor.workers, trials - done))]
            specs = []
            for trial in batch:
                try:
                    specs.append((trial, problem.spec(dict(trial.params))))
                except ConfigError as exc:  # a value the scenario refuses here: this trial's failure
                    _record(study, trial, problem, {"status": STATUS_FAILED, "error": f"ConfigError: {exc}"})
                    result.failed += 1
                    done += 1
                    bar.update(1)
            pending = {trial.number: trial for trial, _ in specs}
            items = [replace(spec, labels={"trial": trial.number}) for trial, spec in specs]
            keys = [f"bracing-optimize-{trial.number}-{spec.run_id}" for trial, spec in specs]
            for spec, outcome, error in executor.run(_execute_trial, items, keys=keys):
                trial = pending[spec.labels["trial"]]
                row = outcome if outcome is not None else {"status": STATUS_FAILED, "error": f"executor: {error!r}"}
                status = _record(study, trial, problem, {**row, "trial": trial.number})
                pending.pop(trial.number, None)
                result.ran += 1
                done += 1
                if status == STATUS_FAILED:
                    result.failed += 1
                    bar.write(f"trial {trial.number} failed: {trial.user_attrs.get('error')}", sys.stderr)
                if on_trial is not None:
                    on_trial(trial.number, status)
                bar.update(1)
                bar.set_postfix(failed=result.failed, refresh=False)
    except KeyboardInterrupt:
        result.interrupted = True
        executor.cancel()
        # Still running only: a Ctrl-C deferred by _record lands after its trial was told.
        running = {t.number for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))}
        for number in pending.keys() & running:
            study.tell(number, state=TrialState.FAIL)  # no "status": shown as interrupted, not counted
        raise
    finally:
        bar.close()
        result.wall_time_s = time.perf_counter() - start
    return result


def _execute_trial(spec: RunSpec) -> dict[str, Any]:
    """A trial on a worker: the run's row only (the arrays stay on the worker, unused)."""
    return execute_run(spec).row


# -- what the study found ---------------------------------------------------------------------------------
def trial_rows(study: optuna.Study, problem: Problem) -> list[dict[str, Any]]:
    """One row per trial: number, status, the varied values, objectives, constraint margins, the run's metrics."""
    rows = []
    for trial in study.get_trials(deepcopy=False):
        attrs = trial.user_attrs
        row: dict[str, Any] = {"trial": trial.number, "status": attrs.get("status", STATUS_INTERRUPTED)}
        row["error"] = attrs.get("error")
        row.update({v.name: trial.params.get(v.name) for v in problem.varies})
        run = dict(attrs.get("row", {}))
        run.pop("status", None)
        run.pop("error", None)
        run.pop("trial", None)
        row.update({key: value for key, value in run.items() if key not in row})
        rows.append(row)
    return rows


def feasible(study: optuna.Study) -> list[optuna.trial.FrozenTrial]:
    """Trials whose run was ok, met the constraints and were told their values."""
    trials = study.get_trials(deepcopy=False)
    return [t for t in trials if t.user_attrs.get("status") == STATUS_OK and t.values is not None]


def pareto_front(trials: Sequence[optuna.trial.FrozenTrial]) -> list[optuna.trial.FrozenTrial]:
    """The trials no other trial dominates (every objective <=, one <), by the first objective."""
    front = [
        t
        for t in trials
        if not any(
            all(a <= b for a, b in zip(o.values, t.values, strict=True)) and o.values != t.values for o in trials
        )
    ]
    return sorted(front, key=lambda t: t.values[0])


def best_trial(study: optuna.Study) -> optuna.trial.FrozenTrial | None:
    """The feasible trial of least first objective (with several objectives: on the Pareto front, the
    least first objective; the front itself is in the report)."""
    candidates = feasible(study)
    return min(candidates, key=lambda t: (t.values[0], t.number)) if candidates else None


def write_best(problem: Problem, trial: optuna.trial.FrozenTrial, path: Path) -> None:
    """A complete scenario file with the trial's values: both nodes' parameters as the trial ran them
    (its duration too), the shared ones under /**, every string quoted (rcl_yaml.dump)."""
    spec = problem.spec(dict(trial.params))
    sim = dict(spec.sim_params, duration=spec.duration)
    ctl = dict(spec.ctl_params)
    shared = {k: v for k, v in sim.items() if k in ctl and ctl[k] == v}  # what the file's /** section holds
    document = {
        "/**": {"ros__parameters": shared},
        SIMULATOR: {"ros__parameters": {k: v for k, v in sim.items() if k not in shared}},
        CONTROLLER: {"ros__parameters": {k: v for k, v in ctl.items() if k not in shared}},
    }
    values = ", ".join(f"{name} = {value!r}" for name, value in trial.params.items())
    objectives = ", ".join(f"{m} = {v:.6g}" for m, v in zip(problem.objectives, trial.values, strict=True))
    header = [
        f"# bracing-optimize: trial {trial.number} of {problem.config} ({values}): {objectives}.",
        "# Every parameter both nodes ran the trial with. Run it: bracing-pair --config <this file>",
    ]
    path.write_text("\n".join(header) + "\n" + rcl_yaml.dump(document))


def reference_rows(problem: Problem, output: Path, executor: Executor) -> dict[str, dict[str, Any]]:
    """The file's setting, passive and free space (as make run's runs), each once per directory."""
    path = output / REFERENCES_FILE
    if path.is_file():
        stored: dict[str, dict[str, Any]] = json.loads(path.read_text())
        if set(stored) == set(REFERENCES):
            return stored
    specs = []
    for name, extra in REFERENCES.items():
        try:
            spec = make_spec(problem.config, {}, problem.duration, overrides={**problem.base, **extra})
        except ConfigError:
            continue  # (a scenario without contacts has no passive run)
        specs.append(replace(spec, labels={"reference": name}))
    rows = {spec.labels["reference"]: row for spec, row, _ in executor.run(_execute_trial, specs) if row is not None}
    path.write_text(json.dumps(rows, indent=2) + "\n")
    return rows


def write_outputs(
    problem: Problem, study: optuna.Study, output: Path, references: dict[str, dict[str, Any]], note: str = ""
) -> optuna.trial.FrozenTrial | None:
    """trials.csv / .parquet, best.yaml (when a trial is feasible), report.md with its figures."""
    rows = trial_rows(study, problem)
    write_sweep_tables(output, rows, ["trial", *(v.name for v in problem.varies)], TRIALS_PARQUET, TRIALS_CSV)
    best = best_trial(study)
    if best is not None:
        write_best(problem, best, output / BEST_YAML)
    write_report(problem, study, output, best, references, note)
    return best


def _cell(value: Any) -> str:
    """A value as the scenario file writes it (true, false) or a metric's cell."""
    return cell(value, bools=("true", "false"))


def changes(problem: Problem, trial: optuna.trial.FrozenTrial) -> list[tuple[str, Any, Any]]:
    """(parameter, the file's value, the optimum's) for every varied parameter."""
    out = []
    for vary in problem.varies:
        if vary.index is None:
            node = CONTROLLER if destination(vary.key) in ("shared", CONTROLLER) else SIMULATOR
            before = problem.base.get(vary.key, node_params(problem.config)[node].get(vary.key))
        else:
            before = problem.lists[vary.key][vary.index]
        out.append((vary.name, before, trial.params[vary.name]))
    return out


def write_report(
    problem: Problem,
    study: optuna.Study,
    output: Path,
    best: optuna.trial.FrozenTrial | None,
    references: dict[str, dict[str, Any]],
    note: str = "",
) -> Path:
    import matplotlib  # imported where used: matplotlib ~460 ms (python -X importtime)

    matplotlib.use("Agg")
    trials = study.get_trials(deepcopy=False)
    statuses = [t.user_attrs.get("status", STATUS_INTERRUPTED) for t in trials]
    count = {s: statuses.count(s) for s in (STATUS_OK, STATUS_INFEASIBLE, STATUS_FAILED, STATUS_INTERRUPTED)}
    command = " ".join(
        ["bracing-optimize", "--config", str(problem.config), *(v.flag for v in problem.varies)]
        + [f"--minimize {m}" for m in problem.objectives]
        + [f"--subject-to '{c.text}'" for c in problem.constraints]
        + ([f"--duration {problem.duration:g}"] if problem.duration else [])
    )
    metrics = list(dict.fromkeys([*problem.objectives, *(c.metric for c in problem.constraints)]))
    lines = [
        f"# Optimisation: {problem.config.name}",
        "",
        f"`{command}`",
        "",
        f"{len(trials)} trials: {count[STATUS_OK]} feasible, {count[STATUS_INFEASIBLE]} infeasible, "
        f"{count[STATUS_FAILED]} failed, {count[STATUS_INTERRUPTED]} interrupted. "
        f"Sampler: {'NSGA-II' if len(problem.objectives) > 1 else 'TPE'} (Optuna), constraints: "
        f"{', '.join(c.text for c in problem.constraints) or 'none'}. {note}",
        "",
    ]
    if best is None:
        lines += ["No feasible trial: no best.yaml.", ""]
    else:
        lines += [
            f"**Optimum** (trial {best.number}; `bracing-pair --config {BEST_YAML}` runs it):",
            "",
            markdown_table(
                ["parameter", "the file's", "optimum"],
                [[name, _cell(before), _cell(after)] for name, before, after in changes(problem, best)],
            ),
            "",
        ]
    runs = ([("optimum", best.user_attrs["row"])] if best is not None else []) + list(references.items())
    table = markdown_table(["run", *metrics], [[name, *(_cell(row.get(m)) for m in metrics)] for name, row in runs])
    lines += [table, "", "![convergence](convergence.png)", ""]
    _draw_convergence(problem, trials, output)
    if len(problem.objectives) == 2:
        front = pareto_front(feasible(study))
        lines += [
            f"**Pareto front** ({len(front)} feasible trials no other beats on both objectives):",
            "",
            "![Pareto front](pareto.png)",
            "",
        ]
        _draw_pareto(problem, study, front, references, output)
    path = output / REPORT
    path.write_text("\n".join(lines))
    return path


def _draw_convergence(problem: Problem, trials: Sequence[optuna.trial.FrozenTrial], output: Path) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    fig = Figure(figsize=(5.5 * len(problem.objectives), 3.8), layout="constrained")
    fig.suptitle(f"{problem.config.stem}: convergence")
    axes = fig.subplots(1, len(problem.objectives), squeeze=False)[0]
    for k, (ax, metric) in enumerate(zip(axes, problem.objectives, strict=True)):
        for status, colour, marker in ((STATUS_OK, "tab:blue", "o"), (STATUS_INFEASIBLE, "grey", "x")):
            points = [(t.number, t.values[k]) for t in trials if t.user_attrs.get("status") == status]
            if points:
                xs, ys = [p[0] for p in points], [p[1] for p in points]
                ax.scatter(xs, ys, s=14, color=colour, marker=marker, label=status)
        best, steps = math.inf, []
        for t in trials:
            if t.user_attrs.get("status") == STATUS_OK:
                best = min(best, t.values[k])
            if math.isfinite(best):
                steps.append((t.number, best))
        if steps:
            ax.step(*zip(*steps, strict=True), where="post", color="tab:red", label="best feasible so far")
        ax.set(xlabel="trial", ylabel=metric, yscale="log" if all(p[1] > 0 for p in steps) and steps else "linear")
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=7)
    fig.savefig(output / "convergence.png", dpi=110)


def _draw_pareto(
    problem: Problem,
    study: optuna.Study,
    front: Sequence[optuna.trial.FrozenTrial],
    references: dict[str, dict[str, Any]],
    output: Path,
) -> None:
    from matplotlib.figure import Figure  # imported where used: matplotlib ~460 ms (python -X importtime)

    x_metric, y_metric = problem.objectives
    fig = Figure(figsize=(6.5, 4.5), layout="constrained")
    ax = fig.subplots()
    for status, colour in ((STATUS_OK, "tab:blue"), (STATUS_INFEASIBLE, "lightgrey")):
        points = [t.values for t in study.get_trials(deepcopy=False) if t.user_attrs.get("status") == status]
        if points:
            ax.scatter([v[0] for v in points], [v[1] for v in points], s=12, color=colour, label=f"{status} trials")
    if front:
        ax.plot([t.values[0] for t in front], [t.values[1] for t in front], "o-", color="tab:red", label="Pareto front")
    for (name, row), marker in zip(references.items(), ("*", "s", "D"), strict=False):
        if number(row.get(x_metric)) and number(row.get(y_metric)):
            ax.scatter([row[x_metric]], [row[y_metric]], marker=marker, s=90, color="black", zorder=5)
            ax.annotate(name, (row[x_metric], row[y_metric]), textcoords="offset points", xytext=(6, 4), fontsize=8)
    ax.set(xlabel=x_metric, ylabel=y_metric, title=f"{problem.config.stem}: {x_metric} against {y_metric}")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.4)
    ax.legend(fontsize=7)
    fig.savefig(output / "pareto.png", dpi=110)


# -- one call for the command and the study ---------------------------------------------------------------
@dataclass
class Optimum:
    best: optuna.trial.FrozenTrial | None
    search: SearchResult
    references: dict[str, dict[str, Any]]
    trials: int  # trials that came back, in all


def optimize(
    problem: Problem,
    output: Path,
    executor: Executor,
    trials: int,
    progress: bool = True,
    seed: int | None = 0,
    references: bool = True,
    first: Sequence[dict[str, float]] = (),
) -> Optimum:
    """Resume or start the study in ``output``, run it to ``trials``, write every output (after Ctrl-C
    too, then re-raising KeyboardInterrupt). ``first``: points a new study tries first (``search``)."""
    check_manifest(problem, output)
    study = open_study(problem, output, seed)
    refs = reference_rows(problem, output, executor) if references else {}
    try:
        result = search(problem, study, executor, trials, progress, first=first)
    except KeyboardInterrupt:
        write_outputs(problem, study, output, refs, "Interrupted: the same command again resumes.")
        raise
    rate = 60.0 * result.ran / result.wall_time_s if result.ran and result.wall_time_s > 0 else None
    note = f"This invocation: {result.ran} trials in {result.wall_time_s:.1f} s on {executor.description}"
    note += f" ({rate:.0f} trials/min)." if rate else "."
    best = write_outputs(problem, study, output, refs, note)
    record_optimisation(output / REPORT, problem.config, search_facts(problem, study, best, seed, result, executor))
    total = sum(1 for t in study.get_trials(deepcopy=False) if counted(t))
    return Optimum(best, result, refs, total)


def search_facts(
    problem: Problem,
    study: optuna.Study,
    best: optuna.trial.FrozenTrial | None,
    seed: int | None,
    result: SearchResult,
    executor: Executor,
) -> dict[str, Any]:
    """The search in one row of the recorded file: trials by status, the sampler, its seed, the best trial, and
    this invocation's trials, wall time [s] and executor."""
    statuses = [t.user_attrs.get("status", STATUS_INTERRUPTED) for t in study.get_trials(deepcopy=False)]
    return {
        "trials": len(statuses),
        "feasible": statuses.count(STATUS_OK),
        STATUS_INFEASIBLE: statuses.count(STATUS_INFEASIBLE),
        STATUS_FAILED: statuses.count(STATUS_FAILED),
        "sampler": f"{'NSGA-II' if len(problem.objectives) > 1 else 'TPE'} (Optuna), seed {seed}",
        "best trial": "none feasible" if best is None else best.number,
        "this invocation": f"{result.ran} trials in {result.wall_time_s:.1f} s on {executor.description}",
    }


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bracing-optimize", description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--config", required=True, type=Path, help="scenario params file")
    parser.add_argument("--vary", action="append", default=[], metavar="KEY=LOW:HIGH", help="a parameter and its range")
    parser.add_argument("--minimize", action="append", default=[], metavar="METRIC", help="an objective (summary key)")
    parser.add_argument("--subject-to", dest="subject_to", action="append", default=[], metavar="'METRIC<=V'")
    add_overrides(parser, "trial")
    parser.add_argument("--trials", type=int, default=100, help="trials in the study, resumed ones included")
    add_duration(parser, "trial")
    add_executor(parser)
    parser.add_argument("--seed", type=int, default=0, help="the sampler's seed")
    add_output(parser, "study")
    add_progress(parser)
    args = parser.parse_args(argv)
    if args.trials < 1:
        parser.error("--trials must be >= 1")
    check_options(parser, args)
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    handle_stop_signals()
    try:
        problem = build_problem(args.config, args.vary, args.minimize, args.subject_to, args.duration, args.sets)
        check_metrics(problem)
        check_manifest(problem, args.output)
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        return config_error("bracing-optimize", exc)
    try:
        with executor:
            print(f"bracing-optimize: up to {args.trials} trials on {executor.description}", file=sys.stderr)
            found = optimize(problem, args.output, executor, args.trials, not args.no_progress, args.seed)
    except KeyboardInterrupt:
        print(
            f"bracing-optimize: interrupted; finished trials kept in {args.output / STUDY_DB}, "
            "the same command again resumes",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    print(summary_text(problem, found, args.output))
    return EXIT_FAILED if found.search.failed else 0


def summary_text(problem: Problem, found: Optimum, output: Path) -> str:
    lines = [
        f"{found.trials} trials ({found.search.ran} now, {found.search.failed} failed now), "
        f"{found.search.wall_time_s:.1f} s; table: {output / TRIALS_CSV}; report: {output / REPORT}"
    ]
    if found.best is None:
        lines.append("no feasible trial")
    else:
        values = ", ".join(f"{k}={_cell(v)}" for k, v in found.best.params.items())
        objectives = ", ".join(f"{m}={_cell(v)}" for m, v in zip(problem.objectives, found.best.values, strict=True))
        lines.append(f"best: trial {found.best.number}: {values}: {objectives}; scenario: {output / BEST_YAML}")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
