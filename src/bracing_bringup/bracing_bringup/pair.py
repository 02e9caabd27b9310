"""bracing-pair: simulator + controller as separate processes over DDS, recorded to rosbag2.

    bracing-pair --config F [--duration S] [--output DIR] [--mode voltage|torque]
                 [--no-bracing] [--real-time] [--domain-id N] [--set KEY=VALUE ...]

Writes DIR/bag/ (mcap), DIR/logs/*.log, DIR/summary.json and the report's PNGs.
Exit 0 on success; non-zero with the failing process's log tail otherwise. Ctrl-C stops
the nodes and still leaves a readable bag.
"""

from __future__ import annotations

import argparse
import copy
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bracing_bringup.domains import hold_domain
from bracing_bringup.overrides import parse_single, route
from bracing_core.config import SimulatorConfig
from bracing_core.controller_config import ControllerConfig
from bracing_core.params import ConfigError, load_params_file

EXIT_FAILED = 1
EXIT_CONFIG = 2
PROGRESS = re.compile(r"progress t=([0-9.eE+-]+)")


@dataclass
class RunOptions:
    config: Path
    output: Path
    duration: float | None = None
    mode: str | None = None
    bracing: bool = True
    real_time: bool = False
    domain_id: int | None = None
    quiet: bool = False
    stall_timeout: float = 60.0  # [s] wall without sim progress before the run is declared hung
    parameters: dict[str, Any] = field(default_factory=dict)  # --set KEY=VALUE (flat names; see overrides)


@dataclass
class RunResult:
    exit_code: int
    output: Path
    wall_time_s: float
    summary: dict[str, Any] | None = None
    message: str = ""
    logs: dict[str, Path] = field(default_factory=dict)


def shared_overrides(options: RunOptions) -> dict[str, Any]:
    """What the command line changes for both nodes (the /** part of the scenario)."""
    common: dict[str, Any] = dict(route(options.parameters).shared)  # --set first: the flags below win
    if options.mode is not None:
        common["input_mode"] = options.mode
    if not options.bracing:
        common["contacts.names"] = []
    return common


def effective_params(options: RunOptions, node: str) -> dict[str, Any]:
    """The flat parameters ``node`` will run with: the scenario file and the command line."""
    params = load_params_file(options.config, node)
    params.update(route(options.parameters).for_node(node))
    params.update(shared_overrides(options))
    return params


def overrides(options: RunOptions, urdf: Path) -> dict[str, dict[str, Any]]:
    """Per-node parameters that win over the scenario file (passed as a second params file).

    The nodes resolve a relative URDF from their working directory, so it is pinned to the
    file found now (``urdf``).
    """
    # Both nodes publish their first message only once the recorder (and, for joint_states, the
    # controller) subscribes to every topic they publish.
    sim: dict[str, Any] = dict(shared_overrides(options), min_subscribers=2, wait_for_recorder=True)
    if options.duration is not None:
        sim["duration"] = options.duration
    if options.real_time:
        sim["stepping"] = "real_time"
    controller = dict(shared_overrides(options), wait_for_recorder=True)
    sim["robot.urdf"] = controller["robot.urdf"] = str(urdf)
    node_sets = route(options.parameters)
    for own, sets in ((sim, node_sets.simulator), (controller, node_sets.controller)):
        own.update({key: value for key, value in sets.items() if key not in own})  # what the pair needs wins
    return {"bracing_simulator": sim, "bracing_controller": controller}


def write_overrides(path: Path, node_overrides: dict[str, dict[str, Any]]) -> None:
    document = {}
    for node, params in node_overrides.items():
        # rcl reads `[]` as NOT_SET, which the configuration reads as an empty list.
        document[node] = {"ros__parameters": copy.deepcopy(params)}  # no shared objects: rcl refuses YAML aliases
    path.write_text(yaml.safe_dump(document, sort_keys=False))


class Pair:
    """The processes of one run and their supervision."""

    def __init__(self, options: RunOptions) -> None:
        self.options = options
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.logs: dict[str, Path] = {}
        self.interrupted = 0  # the signal number that asked to stop, if any

    def say(self, text: str, end: str = "\n") -> None:
        if not self.options.quiet:
            print(text, end=end, flush=True)

    def start(self, name: str, argv: list[str], env: dict[str, str]) -> subprocess.Popen[bytes]:
        log = self.options.output / "logs" / f"{name}.log"
        self.logs[name] = log
        with log.open("wb") as handle:
            proc = subprocess.Popen(argv, stdout=handle, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        self.procs[name] = proc
        return proc

    def stop(self, name: str, timeout: float = 10.0) -> int | None:
        proc = self.procs.get(name)
        if proc is None:
            return None
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.terminate()
                try:
                    proc.wait(3.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        return proc.returncode

    def tail(self, name: str, lines: int = 20) -> str:
        try:
            text = self.logs[name].read_text(errors="replace").splitlines()
        except (KeyError, OSError):
            return ""
        return "\n".join(f"  {name}| {line}" for line in text[-lines:])

    def wait_for_line(self, name: str, needle: str, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if needle in self.logs[name].read_text(errors="replace"):
                return True
            if self.procs[name].poll() is not None:
                return False
            time.sleep(0.05)
        return False

    def sim_time(self) -> float | None:
        try:
            text = self.logs["simulator"].read_text(errors="replace")
        except OSError:
            return None
        found = PROGRESS.findall(text[-4000:])
        return float(found[-1]) if found else None


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


def _run_pair(options: RunOptions, domain: int) -> RunResult:
    start_wall = time.monotonic()
    out = options.output
    sim_config = SimulatorConfig.from_params(effective_params(options, "bracing_simulator"), [options.config.parent])
    ControllerConfig.from_params(effective_params(options, "bracing_controller"), [options.config.parent])
    duration = options.duration if options.duration is not None else sim_config.duration
    bag = out / "bag"
    if bag.exists():
        raise ConfigError(f"--output: {bag} exists already; choose a new output directory")
    (out / "logs").mkdir(parents=True, exist_ok=True)
    override_file = out / "overrides.yaml"
    write_overrides(override_file, overrides(options, sim_config.shared.urdf))

    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = env.get("BRACING_DISCOVERY_RANGE", "LOCALHOST")
    env["ROS_DOMAIN_ID"] = str(domain)
    env["PYTHONUNBUFFERED"] = "1"
    ros_args = ["--ros-args", "--params-file", str(options.config.resolve()), "--params-file", str(override_file)]
    contacts = [c.name for c in sim_config.shared.contacts]
    pair = Pair(options)
    # Ctrl-C or a SIGTERM (a CI timeout, `kill`): stop the nodes in order, keep the bag. The
    # children run in sessions of their own, so nothing else would stop them.
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def on_signal(signum: int, frame: object) -> None:
        pair.interrupted = signum

    for sig in previous:
        signal.signal(sig, on_signal)
    message, code = "", 0
    try:
        pair.say(f"bracing-pair: ROS_DOMAIN_ID={domain}, output {out}")
        pair.start(
            "recorder",
            [
                sys.executable,
                "-m",
                "bracing_bringup.recorder",
                "--output",
                str(bag),
                "--contacts",
                ",".join(contacts),
                "--niceness",
                "10",  # the lockstep loop's two nodes come first; the recorder catches up in their gaps
            ],
            env,
        )
        if not pair.wait_for_line("recorder", "recorder ready", 30.0):
            raise _Failure("recorder", "the recorder did not start")
        pair.start("controller", [sys.executable, "-m", "bracing_controller.node", *ros_args], env)
        pair.start("simulator", [sys.executable, "-m", "bracing_sim.node", *ros_args], env)
        last_progress, last_time, last_shown = time.monotonic(), -1.0, 0.0
        tty = sys.stdout.isatty()
        while True:
            if pair.interrupted:
                raise _Interrupted()
            sim_code = pair.procs["simulator"].poll()
            if sim_code is not None:
                if sim_code != 0:
                    raise _Failure("simulator", f"the simulator exited with code {sim_code}")
                break
            for name in ("controller", "recorder"):
                if pair.procs[name].poll() is not None:
                    raise _Failure(name, f"the {name} exited with code {pair.procs[name].returncode} during the run")
            t = pair.sim_time()
            now = time.monotonic()
            if t is not None and t > last_time:
                last_time, last_progress = t, now
                if now - last_shown >= (0.2 if tty else 2.0) or t >= duration:
                    last_shown = now
                    rtf = t / max(now - start_wall, 1e-9)
                    line = f"  sim {t:7.3f} / {duration:g} s   real-time factor {rtf:5.2f}"
                    pair.say("\r" + line if tty else line, end="" if tty else "\n")
            elif now - last_progress > options.stall_timeout:
                raise _Failure("simulator", f"no simulation progress for {options.stall_timeout:g} s (hung)")
            time.sleep(0.1)
        if tty:
            pair.say("")
    except _Interrupted:
        code = 128 + int(pair.interrupted)
        message = f"interrupted ({signal.Signals(pair.interrupted).name}): nodes stopped, bag finalised"
    except _Failure as failure:
        code = EXIT_FAILED
        message = f"error: {failure.message}\n{pair.tail(failure.process)}"
    finally:
        # Generous grace: the controller flushes its last answers to the recorder (<= 10 s), and a
        # recorder that fell behind on a busy machine drains its queues (<= 60 s) before closing.
        for name, grace in (("simulator", 10.0), ("controller", 15.0), ("recorder", 75.0)):
            pair.stop(name, grace)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    wall = time.monotonic() - start_wall
    if code == 0 and sim_config.stepping == "lockstep" and not options.real_time and duration > 0:
        # Lockstep promises every step in the bag: check it rather than report on a partial record.
        from bracing_bringup.recorder import missing_messages

        problems = missing_messages(bag, contacts, round(duration / sim_config.step) + 1)
        if problems:
            code = EXIT_FAILED
            message = "error: the bag is incomplete (lost messages): " + "; ".join(problems)
    summary = None
    if code == 0:
        from bracing_bringup.report import write_report  # matplotlib: only when there is a report to draw

        summary = write_report(bag, out, wall_time_s=wall)
    return RunResult(code, out, wall, summary, message, pair.logs)


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
    parser.add_argument("--no-bracing", action="store_true", help="the same task with no contacts")
    parser.add_argument("--real-time", action="store_true", help="wall-clock stepping instead of lockstep")
    parser.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS_DOMAIN_ID (default: a free one of 1-100, held exclusively on this machine while the run lives)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    parser.add_argument(
        "--set", dest="sets", action="append", default=[], metavar="KEY=VALUE", help="override a scenario parameter"
    )
    args = parser.parse_args(argv)
    if args.duration is not None and args.duration <= 0:
        parser.error("--duration must be > 0")
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
    )


def main(argv: Sequence[str] | None = None) -> int:
    options = parse_args(argv)
    try:
        result = run_pair(options)
    except ConfigError as exc:
        print(f"bracing-pair: error: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    if result.exit_code != 0:
        print(f"bracing-pair: {result.message}", file=sys.stderr)
        return result.exit_code
    from bracing_bringup.report import format_summary

    print(format_summary(result.summary or {}))
    print(f"bag: {result.output / 'bag'}  report and summary.json: {result.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
