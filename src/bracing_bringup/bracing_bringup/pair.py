"""bracing-pair: simulator + controller as separate processes over DDS, recorded to rosbag2.

    bracing-pair --config F [--duration S] [--output DIR] [--mode voltage|torque]
                 [--no-bracing | --free-space] [--real-time] [--domain-id N] [--set KEY=VALUE ...]
                 [--no-animation] [--timeline] [--network] [--engine bracing|mujoco]

Writes DIR/params.yaml (every parameter the nodes ran with), DIR/bag/ (mcap), DIR/logs/*.log,
DIR/summary.json, the report's PNGs and animation, and DIR/timeline.json (where the wall time
went: see ``timeline``). Exit 0 on success; non-zero with the failing process's log tail
otherwise. Ctrl-C stops the nodes and still leaves a readable bag. A run that fails (or is
stopped) before its first step keeps only its logs, so the same --output works again.

``--engine mujoco``: the robot is MuJoCo's (``bracing_bringup.mujoco_robot``, a mujoco_ros2_control
robot's topic face) and the controller runs unchanged with ``command_output: effort_forward``,
``input_mode: torque`` and ``use_sim_time`` (it follows the robot's /clock); the same bag, summary and
report, with n/a where a metric needs a topic only our simulator has (``contacts``, ``motor_state``).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_bringup.domains import hold_domain
from bracing_bringup.timeline import (
    BAG_CLOSED,
    FIRST_STEP,
    LAST_FILE,
    LAST_STEP,
    TIMELINE_FILE,
    Timeline,
    process_start_time,
    status_event,
)
from bracing_bringup.topics import missing_from_counts
from bracing_bringup.viewurl import free_ports, view_url, wait_for_port
from bracing_core import rcl_yaml, schema
from bracing_core.overrides import CONTROLLER, SIMULATOR, node_params, parse_single, with_layers
from bracing_core.params import ConfigError, resolve_file
from bracing_core.sensing import SensorConfig
from bracing_core.variants import variant_overrides
from bracing_ros.fastdds import NETWORK_ENV
from bracing_ros.lifetime import STOP_WITH_PARENT

if TYPE_CHECKING:
    from bracing_ros.status import Status

EXIT_FAILED = 1
EXIT_CONFIG = 2
PARAMS_FILE = "params.yaml"
"""DIR/params.yaml: every parameter each node ran with (``bracing-simulator --ros-args --params-file``
runs it again)."""
MUJOCO = "mujoco"
MUJOCO_NEEDS = {"command_output": "effort_forward", "input_mode": "torque"}
"""--engine mujoco: the controller's torque law sent as a JointGroupEffortController takes it."""
VIEWER_START_S = 60.0  # [s] --view: how long the viewer may take to serve its page before the run goes on without


@dataclass
class RunOptions:
    config: Path
    output: Path
    duration: float | None = None
    mode: str | None = None
    bracing: bool = True  # False: --no-bracing (no brace tasks; the surfaces stay, as obstacles)
    real_time: bool = False
    domain_id: int | None = None
    quiet: bool = False
    stall_timeout: float = 60.0  # [s] wall without sim progress before the run is declared hung
    parameters: dict[str, Any] = field(default_factory=dict)  # --set KEY=VALUE (flat names; see overrides)
    command_start: float | None = None  # wall time the run was asked for (default: run_pair's call)
    animation: bool = True  # draw animation.gif / .mp4 with the report
    show_timeline: bool = False  # print the timeline at the end (bracing-pair --timeline)
    free_space: bool = False  # --free-space: the surfaces removed (only watched), the paper's comparison
    network: bool = False  # --network: DDS sockets on every interface (default: loopback and shared memory)
    view: bool = False  # --view: bracing-view beside the nodes (a process of its own, best-effort subscriber)
    rrd: bool = False  # --rrd: DIR/run.rrd, the run for rerun's viewer, written from the bag
    engine: str = "bracing"  # --engine: bracing (our simulator) | mujoco (MuJoCo through ros2_control's topics)


@dataclass
class RunResult:
    exit_code: int
    output: Path
    wall_time_s: float
    summary: dict[str, Any] | None = None
    message: str = ""
    logs: dict[str, Path] = field(default_factory=dict)
    timeline: Timeline | None = None


def command_line(options: RunOptions) -> dict[str, Any]:
    """What the command line sets, as flat parameter names: ``--set``, then the flags (they win)."""
    values = dict(options.parameters)
    if options.mode is not None:
        values["input_mode"] = options.mode
    values.update(variant_overrides(options.bracing, options.free_space))
    if options.engine == MUJOCO:
        values.update(MUJOCO_NEEDS)
    return values


def pair_needs(options: RunOptions, urdf: Path) -> dict[str, Any]:
    """What the pair sets over the scenario and the command line, as flat parameter names.

    Both nodes publish their first message only once the recorder has matched every topic they
    publish, and the simulator once the controller has too (joint_states: the controller and the
    recorder; bracing-view subscribes once the run steps) and run_status has its subscribers: this
    process's watcher and the recorder (it keeps the run's warnings), and bracing-view's with --view
    (it is up before the nodes start; counting it makes sure the watcher is one of those matched).
    The nodes resolve a relative URDF from their working directory, so it is pinned to the file
    found now (``urdf``).
    """
    status_subscribers = 2 + int(options.view)
    needs: dict[str, Any] = {
        "wait_for_recorder": True,
        "min_subscribers": 2,
        "min_status_subscribers": status_subscribers,
    }
    if options.duration is not None:
        needs["duration"] = options.duration
    if options.real_time:
        needs["stepping"] = "real_time"
    needs["robot.urdf"] = str(urdf)
    return needs


def write_params(path: Path, node_params: dict[str, dict[str, Any]]) -> None:
    """The nodes' one params file, written so that rcl reads exactly these values back (every string
    quoted: a y stays an axis name, a float list stays floats; no aliases)."""
    path.write_text(rcl_yaml.dump({node: {"ros__parameters": params} for node, params in node_params.items()}))


def _environment(options: RunOptions, domain: int) -> dict[str, str]:
    """The processes' environment: the run's domain, discovery on this machine and, unless
    ``--network``, the loopback-only Fast DDS profile (``bracing_ros.fastdds``)."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = env.get("BRACING_DISCOVERY_RANGE", "LOCALHOST")
    env["ROS_DOMAIN_ID"] = str(domain)
    env["PYTHONUNBUFFERED"] = "1"
    env[STOP_WITH_PARENT] = str(os.getpid())  # they stop should this process be killed
    if options.network:
        env[NETWORK_ENV] = "1"
    return env


class Pair:
    """The processes of one run and their supervision.

    Each process's output goes to DIR/logs/<name>.log through a thread of this process, which
    wakes ``changed`` when the process closes it (exits). What the processes do comes from ROS:
    their run_status messages (``on_status``, from a ``bracing_ros.status.StatusWatcher``) note
    the moments the run waits for (the simulator finished, the recorder closed the bag), the
    simulator's progress and the timeline's events, and wake ``changed`` too: the run reacts at
    once instead of polling.
    """

    def __init__(self, options: RunOptions, timeline: Timeline) -> None:
        self.options = options
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.logs: dict[str, Path] = {}
        self.interrupted = 0  # the signal number that asked to stop, if any
        self.interrupted_procs: set[str] = set()
        self.exited: set[str] = set()
        self.timeline = timeline
        self.changed = threading.Event()  # a watched line came, or a process closed its output
        self.seen: set[str] = set()  # the timeline's events so far (FINISHED, RECORDER_CLOSED, ...)
        self.events: list[tuple[float, str]] = []  # (wall time, what): the first of each
        self.sim_time: float | None = None  # [s] the simulator's last status
        self._followers: dict[str, threading.Thread] = {}

    def say(self, text: str, end: str = "\n") -> None:
        if not self.options.quiet:
            print(text, end=end, flush=True)

    def start(self, name: str, argv: list[str], env: dict[str, str]) -> subprocess.Popen[bytes]:
        log = self.options.output / "logs" / f"{name}.log"
        self.logs[name] = log
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        self.procs[name] = proc
        follower = threading.Thread(target=self._follow, args=(proc, log), name=f"log-{name}", daemon=True)
        follower.start()
        self._followers[name] = follower
        return proc

    def _follow(self, proc: subprocess.Popen[bytes], log: Path) -> None:
        assert proc.stdout is not None
        with log.open("wb") as handle:
            for line in iter(proc.stdout.readline, b""):
                handle.write(line)
                handle.flush()  # the log is whole whenever someone reads it (a failure's tail)
        self.changed.set()  # end of output: the process exited

    def on_status(self, status: Status) -> None:
        """A process's run_status message, from the watcher's thread."""
        if status.node == SIMULATOR and math.isfinite(status.sim_time):
            self.sim_time = status.sim_time
        moment = status_event(status.node, status.event, status.wall_time_s)
        if moment is not None and moment[1] not in self.seen:
            self.events.append(moment)
            self.seen.add(moment[1])
            self.changed.set()

    def wait_for_change(self, timeout: float) -> None:
        """Until a watched line comes or a process exits (at most ``timeout`` [s]); _Interrupted
        if Ctrl-C or SIGTERM asked the run to stop."""
        if self.interrupted:
            raise _Interrupted()
        self.changed.wait(timeout)
        self.changed.clear()

    def exit_code(self, name: str) -> int | None:
        """``name``'s exit code once it has exited and all its output is in its log, else None."""
        code = self.procs[name].poll()
        if code is not None:
            self._followers[name].join(5.0)
        return code

    def interrupt(self, name: str) -> None:
        """SIGINT ``name`` once (a node stops as on Ctrl-C: it flushes, then exits)."""
        proc = self.procs.get(name)
        if proc is not None and proc.poll() is None and name not in self.interrupted_procs:
            self.interrupted_procs.add(name)
            proc.send_signal(signal.SIGINT)

    def stop(self, name: str, timeout: float = 10.0, ask: bool = True) -> int | None:
        """Wait for ``name`` to exit (after a SIGINT unless ``ask`` is False), escalating to SIGTERM
        and SIGKILL after ``timeout``; its exit code."""
        proc = self.procs.get(name)
        if proc is None:
            return None
        if name in self.exited:
            return proc.returncode
        if ask:
            self.interrupt(name)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.interrupt(name)
            proc.terminate()
            try:
                proc.wait(3.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        self._followers[name].join(5.0)
        self.exited.add(name)
        self.timeline.mark(f"{name} exited")
        return proc.returncode

    def kill_all(self) -> None:
        for name, proc in self.procs.items():
            proc.kill()
            proc.wait()
            self._followers[name].join(5.0)
            self.exited.add(name)

    def stop_all(self, ask: bool = True) -> dict[str, int | None]:
        """Stop the processes in order (each after a SIGINT unless ``ask`` is False); their exit codes."""
        # Generous grace: the controller flushes its last answers to the recorder (<= 10 s), and a
        # recorder that fell behind on a busy machine drains its queues (<= 60 s) before closing.
        graces: tuple[tuple[str, float], ...] = (("simulator", 10.0), ("controller", 15.0), ("recorder", 75.0))
        graces += (("viewer", 5.0),) if "viewer" in self.procs else ()  # --view: it stops with the run
        return {name: self.stop(name, grace, ask or name == "viewer") for name, grace in graces}

    def tail(self, name: str, lines: int = 20) -> str:
        try:
            text = self.logs[name].read_text(errors="replace").splitlines()
        except (KeyError, OSError):
            return ""
        return "\n".join(f"  {name}| {line}" for line in text[-lines:])


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


@dataclass(frozen=True)
class RunProcess:
    """One process of a run: bracing-pair starts it as ``python -m module``, launch/pair.launch.py
    as ``package``'s ``executable``; both with these arguments (ours, then ROS's)."""

    name: str  # simulator | controller | recorder
    package: str
    executable: str
    module: str
    arguments: tuple[str, ...]
    ros_arguments: tuple[str, ...] = ()

    def argv(self) -> list[str]:
        ros = ["--ros-args", *self.ros_arguments] if self.ros_arguments else []
        return [sys.executable, "-m", self.module, *self.arguments, *ros]


@dataclass(frozen=True)
class RunPlan:
    """What a run starts, from (scenario file, --set overrides, flags), checked against the schemas
    (names, types, bounds): every node's parameters and the processes. No file is written."""

    options: RunOptions
    sim_values: schema.Values
    node_params: dict[str, dict[str, Any]]  # each node's complete parameters (DIR/params.yaml)
    duration: float  # [s] of sim time
    expected_states: int  # lockstep: the states the recorder waits for before it closes the bag (0: any)

    @property
    def contacts(self) -> list[str]:
        return list(self.sim_values.contacts)

    @property
    def ground_truth(self) -> bool:
        """The simulator measures through sensors (sensors.*): it publishes the truth too, and the bag keeps it."""
        return not SensorConfig.from_values(self.sim_values).exact

    @property
    def search(self) -> list[Path]:
        return [self.options.config.parent]

    def processes(self, out: Path) -> list[RunProcess]:
        """The recorder, the controller and the simulator of a run into ``out`` (its params file
        ``out / PARAMS_FILE``, its bag ``out / "bag"``)."""
        params_file = str(out / PARAMS_FILE)
        recorder = ["--output", str(out / "bag"), "--contacts", ",".join(self.contacts)]
        recorder += ["--ground-truth"] if self.ground_truth else []
        recorder += ["--niceness", "10"]  # the lockstep loop comes first
        recorder += ["--drain-idle", "0.05"]  # stopped only after the nodes' last messages are acknowledged
        recorder += ["--params-file", params_file, "--scenario", self.options.config.stem]  # surfaces, name
        if self.expected_states:
            recorder += ["--expect-states", str(self.expected_states)]  # it closes the bag once it has them all
        nodes = ("--params-file", params_file)
        if self.options.engine == MUJOCO:
            controller = (*nodes, "-p", "use_sim_time:=true")  # it follows MuJoCo's /clock
            mujoco_robot = ("bracing_bringup", "bracing-mujoco-robot", "bracing_bringup.mujoco_robot", (), nodes)
            return [
                RunProcess(
                    "recorder", "bracing_bringup", "bracing-recorder", "bracing_bringup.recorder", tuple(recorder)
                ),
                RunProcess(
                    "controller", "bracing_controller", "bracing-controller", "bracing_controller.node", (), controller
                ),
                RunProcess("simulator", *mujoco_robot),
            ]
        return [
            RunProcess("recorder", "bracing_bringup", "bracing-recorder", "bracing_bringup.recorder", tuple(recorder)),
            RunProcess("controller", "bracing_controller", "bracing-controller", "bracing_controller.node", (), nodes),
            RunProcess("simulator", "bracing_sim", "bracing-simulator", "bracing_sim.node", (), nodes),
        ]


def plan_run(options: RunOptions) -> RunPlan:
    """The one way a run's parameters are assembled for its nodes (bracing-pair, the launch file):
    the scenario file, then ``--set``, then the flags, then what the pair needs (``overrides``).
    The configurations' own checks (pinocchio's imports, ~0.25 s) are ``_check_configs``'."""
    search = [options.config.parent]
    given = node_params(options.config, command_line(options))
    sim_values = schema.read("simulator", given[SIMULATOR])
    schema.read("controller", given[CONTROLLER])  # refused here, before any process starts
    urdf = resolve_file(sim_values["robot.urdf"], "robot.urdf", search)
    duration = options.duration if options.duration is not None else float(sim_values["duration"])
    step = float(sim_values["step"])
    lockstep = sim_values["stepping"] == "lockstep" and not options.real_time and duration > 0
    lockstep = lockstep and options.engine != MUJOCO  # MuJoCo's robot promises no message count
    expected_states = round(duration / step) + 1 if lockstep else 0
    every = with_layers(given, pair_needs(options, urdf))
    return RunPlan(options, sim_values, every, duration, expected_states)


def _run_pair(options: RunOptions, domain: int) -> RunResult:
    timeline = Timeline(options.command_start if options.command_start is not None else time.time())
    start_wall = time.monotonic()
    out = options.output
    plan = plan_run(options)  # checked against the schemas; the configurations' checks follow while processes import
    duration, contacts = plan.duration, plan.contacts
    bag = out / "bag"
    if bag.exists():
        raise ConfigError(f"--output: {bag} exists already; choose a new output directory")
    created = not out.exists()
    (out / "logs").mkdir(parents=True, exist_ok=True)
    params_file = out / PARAMS_FILE
    write_params(params_file, plan.node_params)  # the nodes read only this file
    env = _environment(options, domain)
    pair = Pair(options, timeline)
    # Ctrl-C or a SIGTERM (a CI timeout, `kill`): stop the nodes in order, keep the bag. The
    # children run in sessions of their own, so nothing else would stop them.
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def on_signal(signum: int, frame: object) -> None:
        pair.interrupted = signum

    for sig in previous:
        signal.signal(sig, on_signal)
    message, code, finished = "", 0, False
    watcher = None  # the run_status watcher, once the processes are started
    warnings: list[str] = []  # the controller's configuration warnings (_check_configs); the simulator's: the bag
    try:
        pair.say(f"bracing-pair: ROS_DOMAIN_ID={domain}, output {out}")
        # All three at once: each imports and discovers the others while the rest start. No state
        # goes out before the recorder is there: the simulator steps only once the recorder (and
        # the controller) subscribe to every topic it publishes, and the controller answers only
        # once the recorder subscribes to its outputs (the nodes' wait_for_recorder).
        if options.view:
            # First, and waited for until its page is up (it subscribes before it serves): its imports
            # then do not compete with the stepping, and it sees the run from the first state. It
            # subscribes best effort, so once running it never holds the loop back.
            web_port, grpc_port = free_ports(2)
            ports = ["--web-port", str(web_port), "--grpc-port", str(grpc_port)]
            viewer = [sys.executable, "-m", "bracing_bringup.view", *ports, "--params-file", str(params_file)]
            viewer += ["--after-stepping"]  # not counted as the recorder by the nodes' wait (see view.Live)
            viewer += ["--ros-args", "-p", f"contacts:={contacts!r}"]
            pair.start("viewer", viewer, env)
            url = view_url(web_port, grpc_port)
            if wait_for_port(web_port, lambda: pair.exit_code("viewer") is None, VIEWER_START_S):
                pair.say(f"bracing-pair: watch it at {url}  (log: {out / 'logs' / 'viewer.log'})")
            else:
                pair.say(f"bracing-pair: the viewer did not start (see {out / 'logs' / 'viewer.log'}); running without")
            timeline.mark("viewer started")
        for process in plan.processes(out):
            pair.start(process.name, process.argv(), env)
        timeline.mark("processes started")
        try:
            warnings = _check_configs(plan)
        except Exception:  # a ConfigError (or a fault of the checks themselves): the run never starts
            pair.kill_all()  # they would stop on the same error; nothing of the run is kept
            _discard(out, created, keep_logs=False)
            raise
        timeline.mark("configuration checked")
        # What they do, from ROS: their run_status messages. The watcher's participant starts (in its
        # thread) while the processes still import (~1 s); the simulator steps only once it matched
        # (min_status_subscribers), and the topic keeps a process's history for a late subscriber.
        from bracing_ros.status import StatusWatcher  # rclpy (~0.1 s): after the check, not competing with it

        watcher = StatusWatcher(domain, pair.on_status, env).start()
        last_progress, last_time, last_shown = time.monotonic(), -1.0, 0.0
        tty = sys.stdout.isatty()
        while FINISHED not in pair.seen:  # the simulator's last messages are acknowledged by every subscriber
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
                if exit_code is not None and FINISHED not in pair.seen and (name != "recorder" or exit_code != 0):
                    raise _Failure(name, f"the {name} exited with code {exit_code} during the run")
            t, now = pair.sim_time, time.monotonic()
            if t is not None and t > last_time:
                last_time, last_progress = t, now
                if now - last_shown >= (0.2 if tty else 2.0):
                    last_shown = now
                    rtf = t / max(now - start_wall, 1e-9)
                    line = f"  sim {t:7.3f} / {duration:g} s   real-time factor {rtf:5.2f}"
                    pair.say("\r" + line if tty else line, end="" if tty else "\n")
            elif now - last_progress > options.stall_timeout:
                raise _Failure("simulator", f"no simulation progress for {options.stall_timeout:g} s (hung)")
        finished = True
        if tty:
            pair.say("")
        from bracing_analysis.drawing import prepare_drawing  # rosbags and numpy: needed from here on

        prepare_drawing()  # the drawing processes load matplotlib while the nodes exit and the bag is read
        # The controller's answers are all out (the simulator had the last one): it flushes and exits
        # while the simulator exits by itself. The recorder closes the bag once it has every message
        # (or, should some be missing, when stopped after both nodes are gone).
        pair.interrupt("controller")
        deadline = time.monotonic() + 120.0  # the nodes' flush (<= 15 s) and the recorder's drain (<= 75 s)
        while RECORDER_CLOSED not in pair.seen and pair.exit_code("recorder") is None:
            if time.monotonic() > deadline:
                raise _Failure("recorder", "the recorder did not close the bag")
            if pair.exit_code("simulator") is not None and pair.exit_code("controller") is not None:
                pair.interrupt("recorder")
            pair.wait_for_change(0.1)
    except _Interrupted:
        code = 128 + int(pair.interrupted)
        message = f"interrupted ({signal.Signals(pair.interrupted).name}): nodes stopped, bag finalised"
    except _Failure as failure:
        code = EXIT_FAILED
        message = f"error: {failure.message}\n{pair.tail(failure.process)}"
    finally:
        if not finished or code != 0:
            pair.stop_all()
        if watcher is not None:
            watcher.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    wall = time.monotonic() - start_wall
    summary = None
    timeline.add(pair.events)
    if code == 0:
        timeline.mark(BAG_CLOSED, timeline.at("recorder closed the bag"))
        # The report is drawn while the processes finish exiting (their exit codes are checked after).
        summary, code, message = _report(bag, out, plan, wall, timeline, warnings)
        for name, process_code in pair.stop_all(ask=False).items():
            if process_code != 0 and code == 0 and name != "viewer":  # a viewer's end is no run's failure
                code, message = EXIT_FAILED, f"error: the {name} exited with code {process_code}\n{pair.tail(name)}"
    if code != 0 and timeline.at("simulator stepping") is None:
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
    return RunResult(code, out, wall, summary, message, pair.logs, timeline)


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


def _check_configs(plan: RunPlan) -> list[str]:
    """The nodes' configurations built as an in-process run builds them (``rollout``: they would stop
    on the same error), the start posture's feasibility and the task's rank there: ConfigError,
    before the run leaves a bag behind. The targets out of the arm's reach: warnings, as the
    controller logs them (the summary's)."""
    from bracing_core.checks import reach_warnings
    from bracing_core.rollout import build_scenario_from_params

    scenario = build_scenario_from_params(plan.node_params[SIMULATOR], plan.node_params[CONTROLLER], plan.search)
    assert scenario.controller is not None  # built with the controller's parameters
    return reach_warnings(scenario.controller.config, scenario.controller.plant)


FINISHED = "simulator finished"
"""The simulator's last status: every subscriber has acknowledged everything it sent."""
RECORDER_CLOSED = "recorder closed the bag"


def _report(
    bag: Path, out: Path, plan: RunPlan, wall: float, timeline: Timeline, warnings: list[str]
) -> tuple[dict[str, Any] | None, int, str]:
    """Read the bag once: check it (a lockstep run promises every step), then write the summary
    (with ``warnings``), the figures and the animation from what was read. (summary, exit code, message)."""
    from bracing_analysis.animation import DEFAULT_INTERVAL_S
    from bracing_analysis.bag import BagReadError, read_series  # rosbags ~100 ms, bag replay only, where used
    from bracing_analysis.drawing import report_series

    try:
        series = read_series(bag)
    except BagReadError as exc:
        return None, EXIT_FAILED, f"error: {exc}"
    timeline.mark("bag read")
    options, expected_states = plan.options, plan.expected_states
    if options.engine == MUJOCO:  # no `contacts` topic: each contact's forces and residual from its wrench
        from bracing_analysis.wrench_contacts import contacts_from_wrenches

        contacts_from_wrenches(series)
        series.input_mode = "torque"  # what MUJOCO_NEEDS set (no motor_command tells it)
    if expected_states:  # lockstep
        problems = missing_from_counts(series.topic_counts, plan.contacts, expected_states, "", plan.ground_truth)
        timeline.mark("bag checked")
        if problems:
            return None, EXIT_FAILED, "error: the bag is incomplete (lost messages): " + "; ".join(problems)
    interval = DEFAULT_INTERVAL_S if options.animation else None
    summary = report_series(
        series, out, wall_time_s=wall, animation_interval_s=interval, mark=timeline.mark, warnings=warnings
    )
    timeline.mark(LAST_FILE)
    return summary, 0, ""


class _Failure(Exception):
    def __init__(self, process: str, message: str) -> None:
        super().__init__(message)
        self.process, self.message = process, message


class _Interrupted(Exception):
    pass


def parse_args(argv: Sequence[str] | None) -> RunOptions:
    parser = argparse.ArgumentParser(prog="bracing-pair", description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument(
        "--config", required=True, type=Path, help="scenario params file (e.g. config/paper_4link.yaml)"
    )
    parser.add_argument("--duration", type=float, default=None, help="sim time [s] (default: the file's)")
    parser.add_argument("--output", type=Path, default=None, help="run directory (default: out/<time>)")
    parser.add_argument("--mode", choices=("voltage", "torque"), default=None, help="input mode override")
    parser.add_argument(
        "--no-bracing",
        action="store_true",
        help="the same task with no brace tasks and no desired forces; the surfaces stay as obstacles",
    )
    parser.add_argument(
        "--free-space", action="store_true", help="the surfaces removed (the paper's comparison); implies --no-bracing"
    )
    parser.add_argument("--real-time", action="store_true", help="wall-clock stepping instead of lockstep")
    parser.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS_DOMAIN_ID (default: a free one of 1-100, held exclusively on this machine while the run lives)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    parser.add_argument(
        "--no-animation", action="store_true", help="no animation.gif / .mp4 (the report's figures only)"
    )
    parser.add_argument(
        "--timeline", action="store_true", help="print where the run's wall time went (also in DIR/timeline.json)"
    )
    parser.add_argument(
        "--network",
        action="store_true",
        help=f"DDS sockets on every interface, reachable from other machines (default: loopback and shared "
        f"memory only; {NETWORK_ENV}=1 does the same for nodes started by hand). Use SROS2 to do it securely",
    )
    parser.add_argument("--view", action="store_true", help="watch the run in a browser (bracing-view, 127.0.0.1)")
    parser.add_argument("--rrd", action="store_true", help="also write DIR/run.rrd (open with bracing-view or rerun)")
    parser.add_argument(
        "--engine",
        choices=("bracing", MUJOCO),
        default="bracing",
        help="the physics: bracing (our simulator) or mujoco (MuJoCo as a ros2_control robot; torque input, "
        "the controller's effort_forward output)",
    )
    parser.add_argument(
        "--set", dest="sets", action="append", default=[], metavar="KEY=VALUE", help="override a scenario parameter"
    )
    args = parser.parse_args(argv)
    if args.duration is not None and args.duration <= 0:
        parser.error("--duration must be > 0")
    if args.engine == MUJOCO and args.mode == "voltage":
        parser.error("--engine mujoco drives the joints' torques (a JointGroupEffortController): no --mode voltage")
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        parser.error("--domain-id must be in 0-232 (ROS documents 0-101 as safe on Linux)")
    try:
        parameters = parse_single(args.sets)
    except ConfigError as exc:
        parser.error(str(exc))
    output = args.output or Path("out") / time.strftime("%Y%m%d-%H%M%S")
    return RunOptions(
        args.config,
        output,
        args.duration,
        args.mode,
        not args.no_bracing,
        args.real_time,
        args.domain_id,
        args.quiet,
        parameters=parameters,
        animation=not args.no_animation,
        show_timeline=args.timeline,
        free_space=args.free_space,
        network=args.network,
        view=args.view,
        rrd=args.rrd,
        engine=args.engine,
    )


def main(argv: Sequence[str] | None = None) -> int:
    options = parse_args(argv)
    options.command_start = process_start_time()  # the timeline counts the interpreter's start too
    try:
        result = run_pair(options)
    except ConfigError as exc:
        print(f"bracing-pair: error: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    if result.exit_code != 0:
        print(f"bracing-pair: {result.message}", file=sys.stderr)
        return result.exit_code
    from bracing_analysis.summary import format_summary  # numpy: only once the run is over

    print(format_summary(result.summary or {}))
    print(f"bag: {result.output / 'bag'}  report and summary.json: {result.output}")
    if options.rrd:
        from bracing_bringup.view import write_rrd

        write_rrd(result.output / "bag", result.output / "run.rrd")
        print(f"rerun recording: {result.output / 'run.rrd'}  (bracing-view {result.output / 'bag'} to watch it)")
    if options.show_timeline and result.timeline is not None:
        print(result.timeline.format())
        phases = result.timeline.phases()
        print("  ".join(f"{k} {v:.2f}" for k, v in phases.items() if v is not None))
    return 0


if __name__ == "__main__":
    sys.exit(main())
