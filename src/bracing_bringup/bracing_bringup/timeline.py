"""Where the wall time of one run goes, from the command to the last file written.

A run's processes say what they do on the run_status topic (``bracing_ros.status``: each
message stamped with the wall clock); the pair adds its own moments. ``Timeline`` collects both as (wall time, what) and
splits the run into the phases ``make bench`` reports:

- ``startup_s``: the command's process start to the first simulation step (imports, rclpy's
  re-exec, the nodes' configuration, discovery and matching, the wait for the recorder);
- ``stepping_s``: the first step to the last (the simulator's FINISHED status);
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
import time
from pathlib import Path
from typing import Any

from bracing_core.overrides import CONTROLLER, SIMULATOR
from bracing_recorder.topics import RECORDER_NODE

TIMELINE_FILE = "timeline.json"
PHASES = ("startup_s", "stepping_s", "shutdown_s", "report_s", "whole_run_s")

FIRST_STEP = "first step"
LAST_STEP = "last step"
BAG_CLOSED = "bag closed"
LAST_FILE = "last file written"


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


PROCESSES = {SIMULATOR: "simulator", CONTROLLER: "controller", RECORDER_NODE: "recorder"}
"""The run's node names and the processes they are (run_status says the node)."""
EVENT_LABELS = {
    ("simulator", "configured"): "simulator configured",
    ("simulator", "stepping"): "simulator stepping",
    ("simulator", "finished"): "simulator finished",
    ("controller", "configured"): "controller configured",
    ("controller", "stepping"): "controller answering",
    ("recorder", "ready"): "recorder ready",
    ("recorder", "bag closed"): "recorder closed the bag",
}
"""The timeline's moments, by (process, run_status event): the first of each counts."""


def status_event(node: str, event: str, wall_time_s: float) -> tuple[float, str] | None:
    """A run_status message as a moment of the timeline (wall time, what), or None if it is none."""
    label = EVENT_LABELS.get((PROCESSES.get(node, node), event))
    return None if label is None else (wall_time_s, label)


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
