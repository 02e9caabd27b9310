"""A run supervised from its plan to its files (``run_pair``): the processes started, followed until the
simulator finished and the recorder closed the bag, the bag checked and the report drawn from it.

A run that fails (or is stopped) before its first step keeps only its logs, so the same --output works
again. The run holds its ROS domain id (``domains``) from before its first process starts until its
last file is written.
"""

from __future__ import annotations

import shutil
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from bracing_bringup.domains import hold_domain
from bracing_bringup.processes import Interrupted, Pair, environment
from bracing_bringup.run_plan import PARAMS_FILE, RunOptions, RunPlan, check_configs, plan_run, write_params
from bracing_bringup.timeline import BAG_CLOSED, FIRST_STEP, LAST_FILE, LAST_STEP, TIMELINE_FILE, Timeline
from bracing_core.failures import DIVERGED, EXIT_DIVERGED, EXIT_NODE_FAILED, FAILED, NODE_FAILED, Failure
from bracing_core.params import ConfigError
from bracing_recorder.topics import missing_from_counts
from bracing_view.viewurl import free_ports, view_url, wait_for_port

if TYPE_CHECKING:
    from bracing_analysis.series import BagSeries
    from bracing_ros.status import StatusWatcher

EXIT_FAILED = 1
VIEWER_START_S = 60.0  # [s] --view: how long the viewer may take to serve its page before the run goes on without
FINISHED = "simulator finished"
"""The simulator's last status: every subscriber has acknowledged everything it sent."""
RECORDER_CLOSED = "recorder closed the bag"
EARLY_DRAWING_MAX_S = 1.0
"""[s] of sim time: a run this short starts its drawing processes with its nodes, not at its end. Their
~0.8 s import would otherwise follow a stepping of a fraction of a second: a 0.01 s run's command took
3.26 s instead of 4.04 (medians of 4 alternated, a loaded machine); a longer run's stepping
would share its cores with the import (10-15 % slower on a 4 s run)."""


@dataclass
class RunResult:
    exit_code: int
    output: Path
    wall_time_s: float
    summary: dict[str, Any] | None = None
    message: str = ""
    logs: dict[str, Path] = field(default_factory=dict)
    timeline: Timeline | None = None
    series: BagSeries | None = None
    """The bag as read for the report of a run that ended well (None otherwise): a comparison of runs draws
    from it instead of reading the bag again."""


class Session(Protocol):
    """Processes kept between runs (``bracing_bringup.session``), as a run sees them."""

    @property
    def running(self) -> bool: ...  # processes are kept: the run goes through them

    def prepare(self, plan: RunPlan) -> None: ...  # the run's parameters as kept processes need them

    def pair_for(self, options: RunOptions, timeline: Timeline) -> Pair: ...  # the kept processes, or new ones

    def started(self, watcher: StatusWatcher) -> None: ...  # new processes started: kept from now on

    def begin(self, plan: RunPlan) -> None: ...  # the next run begun through the kept processes

    def close(self) -> dict[str, int | None]: ...  # the kept processes stopped


class _Failure(Exception):
    def __init__(self, process: str, message: str) -> None:
        super().__init__(message)
        self.process, self.message = process, message


class _Diverged(_Failure):
    """The simulator stopped on a divergence: the run's bag and summary are still written, up to it."""


class _NodeFailed(_Failure):
    """A node said the exception that ended its run (``bracing_ros.node_failure``): the run's bag and summary are
    still written, up to it."""


@dataclass
class _Outcome:
    """How the supervised part of a run ended."""

    code: int = 0
    message: str = ""
    warnings: list[str] = field(default_factory=list)  # the controller's configuration warnings (check_configs)
    failed: str = ""  # the process whose failure ended the run
    sim_time: float | None = None  # [s] the simulator's last status when the run failed
    diverged: bool = False  # the simulator stopped on a divergence: the report is drawn from the bag up to it
    node_error: str | None = None  # what a node said of the exception that ended the run: the report as diverged's


def run_pair(options: RunOptions) -> RunResult:
    """Run one experiment; never raises for a failing node, returns the exit code and message.

    The run holds its ROS domain id (see ``domains``) from before its first process starts
    until its last file is written, so no other run on this machine can answer its nodes.
    """
    with hold_domain(options.domain_id) as domain:
        if not domain.exclusive:
            print(
                f"bracing-pair: warning: ROS_DOMAIN_ID={domain.domain_id} (--domain-id) is held by another run on this "
                "machine; their nodes can see each other",
                file=sys.stderr,
                flush=True,
            )
        return _run_pair(options, domain.domain_id)


def _run_pair(options: RunOptions, domain: int, session: Session | None = None) -> RunResult:
    """One run, its processes fresh or (``session``) those the session keeps between runs."""
    timeline = Timeline(options.command_start if options.command_start is not None else time.time())
    start_wall = time.monotonic()
    plan = plan_run(options)  # checked against the schemas; the configurations' checks follow while processes import
    out = options.output
    if (out / "bag").exists():
        raise ConfigError(f"--output: {out / 'bag'} exists already; choose a new output directory")
    created = not out.exists()
    (out / "logs").mkdir(parents=True, exist_ok=True)
    if session is not None:
        session.prepare(plan)
    write_params(out / PARAMS_FILE, plan.node_params)  # the nodes read only this file
    pair = Pair(options, timeline) if session is None else session.pair_for(options, timeline)
    with _stopped_by_signals(pair):
        outcome = _supervise(pair, plan, domain, created, start_wall, session)
    wall = time.monotonic() - start_wall
    keep = session is not None and outcome.code == 0
    result = _conclude(pair, plan, outcome, wall, created, keep)
    if session is not None and result.exit_code != 0:
        session.close()  # a failed run ends the session: the next run starts fresh processes
    return result


@contextmanager
def _stopped_by_signals(pair: Pair) -> Iterator[None]:
    """Ctrl-C or a SIGTERM (a CI timeout, `kill`) while inside: stop the nodes in order, keep the bag.
    The children run in sessions of their own, so nothing else would stop them."""
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def on_signal(signum: int, frame: object) -> None:
        pair.interrupted = signum

    for sig in previous:
        signal.signal(sig, on_signal)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _supervise(
    pair: Pair, plan: RunPlan, domain: int, created: bool, start_wall: float, session: Session | None = None
) -> _Outcome:
    """Start the processes (or, in a ``session`` that has them, begin the next run through them) and follow
    them until the bag is closed; stop them all should the run fail."""
    outcome, finished, watcher = _Outcome(), False, None
    env = environment(plan.options, domain)
    try:
        pair.say(f"bracing-pair: ROS_DOMAIN_ID={domain}, output {plan.options.output}")
        if session is not None and session.running:
            outcome.warnings = check_configs(plan)
            session.begin(plan)  # the next bag asked for, the per-run parameters set, the simulation reset
            _follow_stepping(pair, plan, start_wall)
            finished = True
            _await_closed(pair)
            return outcome
        outcome.warnings = _start(pair, plan, env, created, stay=session is not None)
        if plan.duration <= EARLY_DRAWING_MAX_S:
            from bracing_analysis.drawing import prepare_drawing

            prepare_drawing()
        # What they do, from ROS: their run_status messages. The watcher's participant starts (in its
        # thread) while the processes still import (~1 s); the simulator steps only once it matched
        # (min_status_subscribers), and the topic keeps a process's history for a late subscriber.
        from bracing_ros.status import StatusWatcher  # rclpy (~0.1 s): after the check, not competing with it

        watcher = StatusWatcher(domain, pair.on_status, env).start()
        if session is not None:
            session.started(watcher)
        _follow_stepping(pair, plan, start_wall)
        finished = True
        from bracing_analysis.drawing import prepare_drawing  # rosbags and numpy: needed from here on

        prepare_drawing()  # the drawing processes load matplotlib while the nodes exit and the bag is read
        _await_closed(pair) if session is not None else _await_bag(pair)
    except Interrupted:
        outcome.code = 128 + int(pair.interrupted)
        outcome.message = f"interrupted ({signal.Signals(pair.interrupted).name}): nodes stopped, bag finalised"
    except _Diverged as failure:
        outcome.code, outcome.diverged = EXIT_DIVERGED, True
        outcome.message = f"error: {failure.message}\n{pair.tail(failure.process)}"
        _keep_bag(pair, outcome)
    except _NodeFailed as failure:
        outcome.code, outcome.failed, outcome.sim_time = EXIT_FAILED, failure.process, pair.sim_time
        outcome.node_error = failure.message
        outcome.message = f"error: {failure.message}\n{pair.tail(failure.process)}"
        pair.interrupt("simulator")  # the controller failed: the simulator would wait for its answers
        _keep_bag(pair, outcome)
    except _Failure as failure:
        outcome.code, outcome.failed, outcome.sim_time = EXIT_FAILED, failure.process, pair.sim_time
        outcome.message = f"error: {failure.message}\n{pair.tail(failure.process)}"
    finally:
        if not finished or outcome.code != 0:
            pair.stop_all()
        if watcher is not None and session is None:
            watcher.stop()
    return outcome


def _start(pair: Pair, plan: RunPlan, env: dict[str, str], created: bool, stay: bool = False) -> list[str]:
    """Start the viewer (--view), then the processes (``stay``: the recorder stays for the next bag), and check
    the configurations while they import; the controller's configuration warnings. A ConfigError kills them and
    discards the run."""
    # All three at once: each imports and discovers the others while the rest start. No state
    # goes out before the recorder is there: the simulator steps only once the recorder (and
    # the controller) subscribe to every topic it publishes, and the controller answers only
    # once the recorder subscribes to its outputs (the nodes' wait_for_recorder).
    out = plan.options.output
    if plan.options.view:
        _start_viewer(pair, plan, env)
    for process in plan.processes(out):
        pair.start(process.name, process.argv() + (["--stay"] if stay and process.name == "recorder" else []), env)
    pair.timeline.mark("processes started")
    try:
        warnings = check_configs(plan)
    except Exception:  # a ConfigError (or a fault of the checks themselves): the run never starts
        pair.kill_all()  # they would stop on the same error; nothing of the run is kept
        _discard(out, created, keep_logs=False)
        raise
    pair.timeline.mark("configuration checked")
    return warnings


def _start_viewer(pair: Pair, plan: RunPlan, env: dict[str, str]) -> None:
    """bracing-view, first, and waited for until its page is up (it subscribes before it serves): its
    imports then do not compete with the stepping, and it sees the run from the first state. It
    subscribes best effort, so once running it never holds the loop back."""
    out = plan.options.output
    web_port, grpc_port = free_ports(2)
    ports = ["--web-port", str(web_port), "--grpc-port", str(grpc_port)]
    viewer = [sys.executable, "-m", "bracing_view.view", *ports, "--params-file", str(out / PARAMS_FILE)]
    viewer += ["--after-stepping"]  # not counted as the recorder by the nodes' wait (see view.Live)
    viewer += ["--ros-args", "-p", f"contacts:={plan.contacts!r}"]
    pair.start("viewer", viewer, env)
    url = view_url(web_port, grpc_port)
    if wait_for_port(web_port, lambda: pair.exit_code("viewer") is None, VIEWER_START_S):
        pair.say(f"bracing-pair: watch it at {url}  (log: {out / 'logs' / 'viewer.log'})")
    else:
        pair.say(f"bracing-pair: the viewer did not start (see {out / 'logs' / 'viewer.log'}); running without")
    pair.timeline.mark("viewer started")


def _follow_stepping(pair: Pair, plan: RunPlan, start_wall: float) -> None:
    """Until the simulator finished (its last messages acknowledged by every subscriber), showing its
    progress; _Failure if a process exits before or the simulation stalls."""
    options = plan.options
    last_progress, last_time, last_shown = time.monotonic(), -1.0, 0.0
    tty = sys.stdout.isatty()
    while FINISHED not in pair.seen:
        pair.wait_for_change(0.1)
        if pair.exit_code("simulator") == 0 and FINISHED not in pair.seen:
            # Ended, its FINISHED status still in flight (it waits for run_status's subscriber before
            # its first state, so it is heard): its exit code says it finished; the bag check says
            # whether the run is whole.
            heard_by = time.monotonic() + 1.0
            while FINISHED not in pair.seen and time.monotonic() < heard_by:
                pair.wait_for_change(0.1)
            pair.seen.add(FINISHED)
        for name in ("simulator", "controller", "recorder"):
            exit_code = pair.exit_code(name)
            # The recorder may close the bag and exit by itself once it has every message.
            if name == "simulator" and exit_code == EXIT_DIVERGED and FINISHED not in pair.seen:
                raise _Diverged(name, "the simulation diverged")
            if exit_code is not None and FINISHED not in pair.seen and (name != "recorder" or exit_code != 0):
                said = _said(pair, name, NODE_FAILED) if exit_code == EXIT_NODE_FAILED and name != "recorder" else None
                if said is not None:
                    raise _NodeFailed(name, f"the {name} failed: the run failed in {said}")
                raise _Failure(name, f"the {name} exited with code {exit_code} during the run")
        t, now = pair.sim_time, time.monotonic()
        if t is not None and t > last_time:
            last_time, last_progress = t, now
            if now - last_shown >= (0.2 if tty else 2.0):
                last_shown = now
                rtf = t / max(now - start_wall, 1e-9)
                line = f"  sim {t:7.3f} / {plan.duration:g} s   real-time factor {rtf:5.2f}"
                pair.say("\r" + line if tty else line, end="" if tty else "\n")
        elif now - last_progress > options.stall_timeout:
            raise _Failure("simulator", f"no simulation progress for {options.stall_timeout:g} s (hung)")
    if tty:
        pair.say("")


def _keep_bag(pair: Pair, outcome: _Outcome) -> None:
    """After a divergence: the simulator sent every state up to it before it exited; the controller stops
    and the recorder closes the bag with all of them (``_await_bag``), so the report can be drawn."""
    try:
        _await_bag(pair)
    except (_Failure, Interrupted) as exc:
        outcome.diverged, outcome.node_error = False, None  # no bag to read: the run fails as any other
        outcome.message += f"\n{exc}"


def _await_closed(pair: Pair) -> None:
    """A run through kept processes: until the recorder closed its bag (it then waits for the next); _Failure
    should a process exit meanwhile."""
    deadline = time.monotonic() + 120.0  # the recorder's drain (<= 75 s)
    while RECORDER_CLOSED not in pair.seen:
        exited = [name for name in ("simulator", "controller", "recorder") if pair.exit_code(name) is not None]
        if exited:
            raise _Failure(exited[0], f"the {exited[0]} exited with code {pair.exit_code(exited[0])} during the run")
        if time.monotonic() > deadline:
            raise _Failure("recorder", "the recorder did not close the bag")
        pair.wait_for_change(0.1)


def _await_bag(pair: Pair) -> None:
    """The controller's answers are all out (the simulator had the last one): it flushes and exits
    while the simulator exits by itself. The recorder closes the bag once it has every message (or,
    should some be missing, when stopped after both nodes are gone)."""
    pair.interrupt("controller")
    deadline = time.monotonic() + 120.0  # the nodes' flush (<= 15 s) and the recorder's drain (<= 75 s)
    while RECORDER_CLOSED not in pair.seen and pair.exit_code("recorder") is None:
        if time.monotonic() > deadline:
            raise _Failure("recorder", "the recorder did not close the bag")
        if pair.exit_code("simulator") is not None and pair.exit_code("controller") is not None:
            pair.interrupt("recorder")
        pair.wait_for_change(0.1)
    code = pair.exit_code("recorder")
    if RECORDER_CLOSED not in pair.seen and code not in (None, 0):
        raise _Failure("recorder", f"the recorder exited with code {code} before it closed the bag")


def _conclude(
    pair: Pair, plan: RunPlan, outcome: _Outcome, wall: float, created: bool, keep: bool = False
) -> RunResult:
    """The run's files and result once its processes are done: the report of a run that ended well
    (then the processes' exit codes, unless ``keep``: they stay for the next run), nothing but the logs of one
    that never stepped."""
    out, timeline = plan.options.output, pair.timeline
    code, message, summary, series = outcome.code, outcome.message, None, None
    timeline.add(pair.events)
    if outcome.diverged:  # the report of what ran until the divergence; the exit code stays
        pair.stop_all(ask=False)
        summary, message = _draw_failure(plan, pair, wall, timeline, outcome)
    elif outcome.node_error is not None:  # likewise until a node's failure
        pair.stop_all(ask=False)
        summary, message = _draw_node_failure(plan, wall, timeline, outcome, outcome.node_error)
    if code == 0:
        timeline.mark(BAG_CLOSED, timeline.at("recorder closed the bag"))
        # The report is drawn while the processes finish exiting (their exit codes are checked after).
        series, summary, code, message = _check_and_draw(plan, wall, timeline, outcome.warnings)
        for name, process_code in ({} if keep else pair.stop_all(ask=False)).items():
            if process_code != 0 and code == 0 and name != "viewer":  # a viewer's end is no run's failure
                code, message = EXIT_FAILED, f"error: the {name} exited with code {process_code}\n{pair.tail(name)}"
    recovered = _recover_recording(pair, plan, outcome, wall, message) if code != 0 else None
    if recovered is not None:
        summary, message = recovered
    if code != 0 and not _stepped(timeline, outcome):
        # Nothing to keep from a run that never stepped: the same --output works again.
        _discard(out, created, keep_logs=True)
        if pair.interrupted:
            message = f"interrupted ({signal.Signals(pair.interrupted).name}) before the first step"
        message += f"\n(the run never stepped: nothing of it was kept but its logs, {out / 'logs'})"
        return RunResult(code, out, wall, None, message, pair.logs, timeline)
    for phase, event in ((FIRST_STEP, "simulator stepping"), (LAST_STEP, "simulator finished")):
        stamp = timeline.at(event)
        if stamp is not None:
            timeline.mark(phase, stamp)
    timeline.write(out)
    return RunResult(code, out, wall, summary, message, pair.logs, timeline, series if code == 0 else None)


def _stepped(timeline: Timeline, outcome: _Outcome) -> bool:
    """Whether the simulator stepped: it said so on run_status, or it diverged (only a step diverges; a
    simulator that diverges at once may exit before its STEPPING reaches this process)."""
    return outcome.diverged or timeline.at("simulator stepping") is not None


def _recorder_end(code: int | None) -> str:
    """How the recorder ended, from its exit code (a signal's: negative)."""
    if code is not None and code < 0:
        return f"died (signal {-code}, {signal.Signals(-code).name})"
    return "did not end" if code is None else f"exited with code {code}"


def _recover_recording(
    pair: Pair, plan: RunPlan, outcome: _Outcome, wall: float, message: str
) -> tuple[dict[str, Any] | None, str] | None:
    """A run that failed after its first step with its bag cut short (its recorder died before closing it):
    the bag recovered (``bag_recovery``, with the notes the recorder would have written) and the report
    drawn from it, the recovery said first in the message and in summary.json's warnings. (summary,
    message); None if the bag is not cut short."""
    from bracing_analysis.bag_recovery import RecoveryError, cut_files, recover_bag

    out = plan.options.output
    if not _stepped(pair.timeline, outcome) or not cut_files(out / "bag"):
        return None
    from bracing_recorder.bag_notes import bag_notes_of_values

    said = f"the recorder {_recorder_end(pair.exit_code('recorder'))}"
    if outcome.failed == "recorder":  # said here, with what became of the bag
        message = message.split("\n", 1)[1] if "\n" in message else ""
    try:
        scenario, truth = plan.options.config.stem, plan.ground_truth
        notes = bag_notes_of_values(plan.sim_values, plan.ctl_values, scenario, truth, plan.search)
        recovered = recover_bag(out / "bag", notes)
    except RecoveryError as exc:
        return None, f"error: {said}; the recording is lost: {exc}\n{message}".rstrip("\n")
    pair.timeline.mark("bag recovered")
    # Two lower bounds of when it died: its last message written, the simulator's last progress status.
    bounds = [t for t in (outcome.sim_time, recovered.last_s()) if t is not None]
    said += f" at t >= {max(bounds):.3f} s" if bounds else ""
    upto = f" up to t = {recovered.last_s():.3f} s" if recovered.last_s() is not None else ""
    said += f"; the bag was recovered{upto}: {recovered.messages} messages (what it had not yet written is lost)"
    summary = _draw_recovered(plan, wall, pair.timeline, [said, *outcome.warnings], said)
    return summary, f"error: {said}\n{message}".rstrip("\n")


def _draw_recovered(
    plan: RunPlan, wall: float, timeline: Timeline, warnings: list[str], error: str
) -> dict[str, Any] | None:
    """The report of a recovered bag (no check that it is whole: it is not), its summary's status failed with
    ``error``; None if it cannot be read."""
    from bracing_analysis.bag import BagReadError, read_series

    try:
        series = read_series(plan.options.output / "bag")
    except BagReadError:
        return None
    return _draw(plan, series, wall, timeline, warnings, {"status": "failed", "error": error, "hint": None})


def _discard(out: Path, created: bool, keep_logs: bool) -> None:
    """Remove what a run that never stepped wrote (its empty bag, its params file), and its logs unless
    ``keep_logs``; the directory too if the run made it and it is left empty."""
    shutil.rmtree(out / "bag", ignore_errors=True)
    (out / PARAMS_FILE).unlink(missing_ok=True)
    (out / TIMELINE_FILE).unlink(missing_ok=True)
    if not keep_logs:
        shutil.rmtree(out / "logs", ignore_errors=True)
    if created and out.is_dir() and not any(out.iterdir()):
        out.rmdir()


def _draw_failure(
    plan: RunPlan, pair: Pair, wall: float, timeline: Timeline, outcome: _Outcome
) -> tuple[dict[str, Any] | None, str]:
    """The summary and report of a run the simulator stopped on a divergence, from its bag (every state up
    to the failure: no lockstep count to check), with ``status`` failed, the ``error`` (the simulator's, and
    what ran away) and the ``hint`` (``failures.diagnose``); the message says both."""
    series, unread = _failed_run_series(plan, timeline, outcome)
    if series is None:
        return None, unread
    reason = _divergence(pair)
    try:
        failure = diagnose_pair(plan, series, reason, outcome.warnings)
    except Exception as exc:  # the diagnosis is a help: its own fault must not cost the run its summary
        failure = Failure(FAILED, f"{reason} (what ran away could not be told: {type(exc).__name__}: {exc})", None)
    summary = _draw(plan, series, wall, timeline, outcome.warnings, failure.keys())
    message = f"error: {failure.error}" + (f"\nhint: {failure.hint}" if failure.hint else "")
    return summary, f"{message}\n{_kept_up_to_failure(plan)}"


def _draw_node_failure(
    plan: RunPlan, wall: float, timeline: Timeline, outcome: _Outcome, error: str
) -> tuple[dict[str, Any] | None, str]:
    """The summary and report of a run a node's failure ended, from its bag (every state up to the failure: no
    lockstep count to check), with ``status`` failed and the node's ``error``; the message says it."""
    series, unread = _failed_run_series(plan, timeline, outcome)
    if series is None:
        return None, unread
    summary = _draw(plan, series, wall, timeline, outcome.warnings, {"status": FAILED, "error": error, "hint": None})
    return summary, f"{outcome.message}\n{_kept_up_to_failure(plan)}"


def _failed_run_series(plan: RunPlan, timeline: Timeline, outcome: _Outcome) -> tuple[Any, str]:
    """The bag of a run a failure ended, read for its report: (its series, ""), or (None, the run's message with
    why it could not be read)."""
    from bracing_analysis.bag import BagReadError, read_series

    try:
        series = read_series(plan.options.output / "bag")
    except BagReadError as exc:
        return None, f"{outcome.message}\nerror: {exc}"
    timeline.mark("bag read")
    return series, ""


def _kept_up_to_failure(plan: RunPlan) -> str:
    return f"(summary.json, the bag and the report hold the run up to the failure: {plan.options.output})"


def _divergence(pair: Pair) -> str:
    """What the simulator said of its divergence (its log's line), without the prefix."""
    said = _said(pair, "simulator", DIVERGED)
    return f"simulation diverged at t = {said}" if said else "the simulation diverged (see the simulator's log)"


def _said(pair: Pair, name: str, prefix: str) -> str | None:
    """The rest of the last line of ``name``'s log that says ``prefix`` (a failure's line); None if none does."""
    log = pair.logs.get(name)
    lines = log.read_text(errors="replace").splitlines() if log is not None and log.exists() else []
    said = [line.split(prefix, 1)[1] for line in lines if prefix in line]
    return said[-1] if said else None


def diagnose_pair(plan: RunPlan, series: Any, reason: str, warnings: list[str]) -> Failure:
    """``failures.diagnose`` of a pair run from its bag: the joint states up to the failure (velocities by
    differences), the nodes' configurations as the run built them, every warning of the run."""
    import numpy as np

    from bracing_core.failures import History, diagnose
    from bracing_core.rollout import build_scenario_from_values

    scenario = build_scenario_from_values(plan.sim_values, plan.ctl_values, plan.search)
    assert scenario.controller is not None
    names = list(scenario.plant.joint_names)
    columns = [series.joint_names.index(name) for name in names] if series.joint_t.size else []
    position = series.joint_position[:, columns] if columns else np.zeros((0, len(names)))
    velocity = np.zeros_like(position)
    if series.joint_t.size > 1:
        velocity = np.asarray(np.gradient(position, series.joint_t, axis=0))
    history = History(series.joint_t, position, velocity, names)
    step = (scenario.sim.step_size, scenario.sim.substeps)
    said = [*warnings, *series.warnings]
    return diagnose(reason, history, scenario.plant, scenario.controller.config, step, said)


def _check_and_draw(
    plan: RunPlan, wall: float, timeline: Timeline, warnings: list[str]
) -> tuple[BagSeries | None, dict[str, Any] | None, int, str]:
    """Read the bag once: check it (a lockstep run promises every step), then write the summary
    (with ``warnings``), the figures and the animation from what was read. (what was read, summary, exit code,
    message)."""
    from bracing_analysis.bag import BagReadError, read_series  # rosbags ~100 ms, bag replay only, where used

    out = plan.options.output
    try:
        series = read_series(out / "bag")
    except BagReadError as exc:
        return None, None, EXIT_FAILED, f"error: {exc}"
    timeline.mark("bag read")
    expected_states = plan.expected_states
    if expected_states:  # lockstep
        problems = missing_from_counts(series.topic_counts, plan.contacts, expected_states, "", plan.ground_truth)
        timeline.mark("bag checked")
        if problems:
            return series, None, EXIT_FAILED, "error: the bag is incomplete (lost messages): " + "; ".join(problems)
    return series, _draw(plan, series, wall, timeline, warnings), 0, ""


def _draw(
    plan: RunPlan,
    series: Any,
    wall: float,
    timeline: Timeline,
    warnings: list[str],
    outcome: dict[str, str | None] | None = None,
) -> dict[str, Any]:
    """summary.json (``outcome``: its status, error and hint; None: from the warnings), the figures and the
    animation of ``series``."""
    from bracing_analysis.animation import DEFAULT_INTERVAL_S
    from bracing_analysis.drawing import report_series
    from bracing_core.failures import fed_back

    interval = DEFAULT_INTERVAL_S if plan.options.animation else None
    summary = report_series(
        series,
        plan.options.output,
        wall_time_s=wall,
        animation_interval_s=interval,
        mark=timeline.mark,
        warnings=warnings,
        outcome=outcome,
        fed_back=fed_back(plan.ctl_values),
    )
    timeline.mark(LAST_FILE)
    return summary
