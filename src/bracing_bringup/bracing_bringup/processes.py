"""The processes of one run (``Pair``): started with their output in DIR/logs, followed through their
run_status messages, stopped in order."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from bracing_bringup.run_plan import RunOptions
from bracing_bringup.timeline import Timeline, status_event
from bracing_core.overrides import SIMULATOR
from bracing_ros.fastdds import NETWORK_ENV
from bracing_ros.lifetime import STOP_WITH_PARENT

if TYPE_CHECKING:
    from bracing_ros.status import Status


class Interrupted(Exception):
    """Ctrl-C or SIGTERM asked the run to stop (``Pair.interrupted`` says which)."""


def environment(options: RunOptions, domain: int) -> dict[str, str]:
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

    def next_run(self, options: RunOptions, timeline: Timeline) -> None:
        """The same processes for another run (a session's): its options and timeline, nothing seen yet.
        Their output goes on into this run's DIR/logs from now on."""
        for name in self.logs:
            self.logs[name] = options.output / "logs" / f"{name}.log"
            self.logs[name].touch()
        self.options, self.timeline = options, timeline
        self.interrupted = 0
        self.seen, self.events, self.sim_time = set(), [], None
        self.changed.clear()

    def say(self, text: str, end: str = "\n") -> None:
        if not self.options.quiet:
            print(text, end=end, flush=True)

    def start(self, name: str, argv: list[str], env: dict[str, str]) -> subprocess.Popen[bytes]:
        log = self.options.output / "logs" / f"{name}.log"
        self.logs[name] = log
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        self.procs[name] = proc
        follower = threading.Thread(target=self._follow, args=(proc, name), name=f"log-{name}", daemon=True)
        follower.start()
        self._followers[name] = follower
        return proc

    def _follow(self, proc: subprocess.Popen[bytes], name: str) -> None:
        assert proc.stdout is not None
        log = self.logs[name]
        handle = log.open("wb")
        for line in iter(proc.stdout.readline, b""):
            if self.logs[name] != log:  # a session's next run (next_run): its own log from here on
                handle.close()
                log = self.logs[name]
                handle = log.open("ab")
            handle.write(line)
            handle.flush()  # the log is whole whenever someone reads it (a failure's tail)
        handle.close()
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
        """Until a watched line comes or a process exits (at most ``timeout`` [s]); Interrupted
        if Ctrl-C or SIGTERM asked the run to stop."""
        if self.interrupted:
            raise Interrupted()
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
