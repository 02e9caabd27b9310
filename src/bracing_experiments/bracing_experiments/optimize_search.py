"""bracing-optimize's search: the Optuna study in its directory, trials asked in batches and run on the
sweeps' executors, each told whole (even under Ctrl-C), the reference runs, and ``optimize``: the one call of
the command and the studies."""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from bracing_core.numbers import number
from bracing_core.params import ConfigError
from bracing_core.variants import BRACED, FREE_SPACE, PASSIVE
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import STATUS_OK, RunSpec, execute_run
from bracing_experiments.optimize_record import record_optimisation
from bracing_experiments.optimize_report import REPORT, write_outputs
from bracing_experiments.optimize_specs import STATUS_FAILED, STATUS_INFEASIBLE, STATUS_INTERRUPTED, Problem, Vary
from bracing_experiments.specs import make_spec

if TYPE_CHECKING:
    import optuna

STUDY_DB, STUDY_NAME, MANIFEST = "study.db", "bracing-optimize", "optimize.json"
REFERENCES_FILE = "references.json"
REFERENCES = {  # the file's setting and make run's two other runs (variants.RUNS), marked on the figures
    "file's setting": BRACED.overrides(),
    "passive": PASSIVE.overrides(),
    "free space": FREE_SPACE.overrides(),
}


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
