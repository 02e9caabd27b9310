"""Where the wall time of one run goes, from the command to the last file written.

A run's processes say what they do in their logs (rcutils stamps every line with the wall
clock); the pair adds its own moments. ``Timeline`` collects both as (wall time, what) and
splits the run into the phases ``make bench`` reports:

- ``startup_s``: the command's process start to the first simulation step (imports, rclpy's
  re-exec, the nodes' configuration, discovery and matching, the wait for the recorder);
- ``stepping_s``: the first step to the last (the simulator's "finished" line);
- ``shutdown_s``: the last step to the bag closed (the nodes' flush and exit, the recorder's
  drain, /tf and markers, closing the bag);
- ``report_s``: the bag closed to the last file written (the one read of the bag, its check,
  summary.json, the figures and the animation);
- ``whole_run_s``: the command to the last file.

``DIR/timeline.json`` holds the phases and every event, relative to the command.
"""

from __future__ import annotations

import json
import os
import re
import time
from pathlib import Path
from typing import Any

TIMELINE_FILE = "timeline.json"
PHASES = ("startup_s", "stepping_s", "shutdown_s", "report_s", "whole_run_s")

FIRST_STEP = "first step"
LAST_STEP = "last step"
BAG_CLOSED = "bag closed"
LAST_FILE = "last file written"

_ROS_LINE = re.compile(r"^\[(?P<level>[A-Z]+)\] \[(?P<stamp>[0-9]+\.[0-9]+)\] \[[^\]]*\]: (?P<text>.*)$")
NODE_EVENTS = (
    ("configured", re.compile(r"^(voltage|torque) (input|output)")),
    ("stepping", re.compile(r"^(lockstep|real-time): stepping")),
    ("answering", re.compile(r"^answering joint_states")),
    ("finished", re.compile(r"^finished at t = ")),
)
"""Lines of a node's log that mark a moment of the run (the first of each counts)."""


_RECORDER_LINE = re.compile(r"^recorder (?P<text>subscribed|closed the bag) at (?P<stamp>[0-9]+\.[0-9]+)")
_RECORDER_EVENTS = {"subscribed": "recorder ready", "closed the bag": "recorder closed the bag"}


def recorder_events(log: Path) -> list[tuple[float, str]]:
    """(wall time, "recorder ready" / "recorder closed the bag") from the recorder's output."""
    try:
        lines = log.read_text(errors="replace").splitlines()
    except OSError:
        return []
    matches = [m for line in lines if (m := _RECORDER_LINE.match(line))]
    return [(float(m["stamp"]), _RECORDER_EVENTS[m["text"]]) for m in matches]


def process_start_time(pid: int | None = None) -> float:
    """Wall time [s] at which process ``pid`` (default: this one) started, from /proc (Linux).

    It is the moment of the fork, so it counts the interpreter's start and rclpy's re-exec
    (an exec keeps the process). Falls back to now where /proc is missing."""
    try:
        stat = Path(f"/proc/{pid or os.getpid()}/stat").read_text()
        ticks = int(stat.rsplit(")", 1)[1].split()[19])  # field 22: starttime, in clock ticks after boot
        uptime = float(Path("/proc/uptime").read_text().split()[0])  # [s] after boot, 0.01 s resolution
        return time.time() - (uptime - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, StopIteration):
        return time.time()


def node_events(log: Path, process: str) -> list[tuple[float, str]]:
    """(wall time, "<process> <event>") for the first line of each of ``NODE_EVENTS`` in a node's log."""
    try:
        lines = log.read_text(errors="replace").splitlines()
    except OSError:
        return []
    found: dict[str, float] = {}
    for line in lines:
        match = _ROS_LINE.match(line)
        if match is None:
            continue
        for name, pattern in NODE_EVENTS:
            if name not in found and pattern.match(match["text"]):
                found[name] = float(match["stamp"])
    return [(stamp, f"{process} {name}") for name, stamp in found.items()]


class Timeline:
    """Moments of one run, as wall-clock times (comparable across processes)."""

    def __init__(self, command_start: float | None = None) -> None:
        self.command = process_start_time() if command_start is None else command_start
        self.events: list[tuple[float, str]] = []

    def mark(self, what: str, at: float | None = None) -> None:
        self.events.append((time.time() if at is None else at, what))

    def add(self, events: list[tuple[float, str]]) -> None:
        self.events.extend(events)

    def at(self, what: str) -> float | None:
        return next((stamp for stamp, name in self.events if name == what), None)

    def phases(self) -> dict[str, float | None]:
        """The phases of the module docstring [s]; None where a moment is missing (a failed run)."""
        first, last, closed, end = (self.at(name) for name in (FIRST_STEP, LAST_STEP, BAG_CLOSED, LAST_FILE))

        def span(a: float | None, b: float | None) -> float | None:
            return None if a is None or b is None else b - a

        return {
            "startup_s": span(self.command, first),
            "stepping_s": span(first, last),
            "shutdown_s": span(last, closed),
            "report_s": span(closed, end),
            "whole_run_s": span(self.command, end),
        }

    def as_dict(self) -> dict[str, Any]:
        return {
            **self.phases(),
            "events": [{"t_s": round(stamp - self.command, 4), "what": what} for stamp, what in sorted(self.events)],
        }

    def write(self, directory: Path) -> Path:
        path = directory / TIMELINE_FILE
        path.write_text(json.dumps(self.as_dict(), indent=2) + "\n", encoding="utf-8")
        return path

    def format(self) -> str:
        """The events, one per line, seconds after the command."""
        return "\n".join(f"{stamp - self.command:8.3f} s  {what}" for stamp, what in sorted(self.events))
