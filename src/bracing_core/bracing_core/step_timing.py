"""Where a lockstep step's wall time goes inside a node: the work of each step (decoding, the engine
or the law, building and publishing the answer), without the time spent waiting for the peer. The
nodes log it at a run's end; ``make bench`` reads it into ``pair_step_breakdown_us``."""

from __future__ import annotations

import re
import time

import numpy as np

WORK_LINE = "per-step work [us]"
_PATTERN = re.compile(
    re.escape(WORK_LINE)
    + r": mean ([0-9.]+), p50 ([0-9.]+), p99 ([0-9.]+)(?:, p99.9 ([0-9.]+), max ([0-9.]+))? over ([0-9]+) steps"
    + r"(?:; until the answer is out: mean ([0-9.]+), p50 ([0-9.]+))?"
    + r"(?:; DDS writes: mean ([0-9.]+), p50 ([0-9.]+))?"
)


class WorkTimer:
    """Per-step work [s] on ``time.perf_counter``: ``begin`` a step, ``pause``/``resume`` around a
    wait for the peer, ``mark`` when the answer the peer waits for is out (the simulator's next state:
    what follows it, the step's reports, overlaps the peer's work), ``end`` it with the time its
    messages' DDS writes took (rclpy's publish: the middleware's share of the work). Four to five clock
    reads a step (~0.2 us), two more a message written."""

    def __init__(self) -> None:
        self._samples: list[float] = []
        self._to_mark: list[float] = []
        self._writes: list[float] = []
        self._start = 0.0
        self._waited = 0.0
        self._paused_at = 0.0
        self._marked_at: float | None = None

    def begin(self, at: float | None = None) -> None:
        """A step begins (``at``: when [s] on ``time.perf_counter``'s clock; None: now)."""
        self._start, self._waited, self._marked_at = time.perf_counter() if at is None else at, 0.0, None

    def pause(self) -> None:
        self._paused_at = time.perf_counter()

    def resume(self) -> None:
        self._waited += time.perf_counter() - self._paused_at

    def mark(self, at: float | None = None) -> None:
        """The answer is out (``at``: when, as ``begin``'s)."""
        if self._marked_at is None:
            self._marked_at = time.perf_counter() if at is None else at

    def end(self, written_s: float = 0.0, at: float | None = None) -> None:
        """The step ends (``at``: when, as ``begin``'s; None: now)."""
        self._samples.append((time.perf_counter() if at is None else at) - self._start - self._waited)
        self._writes.append(written_s)
        if self._marked_at is not None:  # the waits come before the answer is taken, so before the mark
            self._to_mark.append(self._marked_at - self._start - self._waited)

    def line(self) -> str | None:
        """The log line (None before any step): mean, p50, p99, p99.9 and the maximum [us] and the count;
        with marks, the mean and p50 up to the mark; with writes, their mean and p50."""
        if not self._samples:
            return None
        us = np.asarray(self._samples) * 1e6
        mean, (p50, p99, p999) = float(us.mean()), np.percentile(us, [50, 99, 99.9])
        line = (
            f"{WORK_LINE}: mean {mean:.1f}, p50 {p50:.1f}, p99 {p99:.1f}, p99.9 {p999:.1f}, max {us.max():.1f} "
            f"over {len(us)} steps"
        )
        if self._to_mark:
            marked = np.asarray(self._to_mark) * 1e6
            line += f"; until the answer is out: mean {marked.mean():.1f}, p50 {np.percentile(marked, 50):.1f}"
        writes = np.asarray(self._writes) * 1e6
        if writes.any():
            line += f"; DDS writes: mean {writes.mean():.1f}, p50 {np.percentile(writes, 50):.1f}"
        return line


def read_work_line(log: str) -> dict[str, float] | None:
    """The last per-step work line of a node's log as {mean, p50, p99 [us], steps} and, where the line has
    them, {p99_9, max}, with marks {out_mean, out_p50} and with writes {writes_mean, writes_p50}; None if
    absent."""
    found = _PATTERN.findall(log)
    if not found:
        return None
    mean, p50, p99, p999, most, steps, out_mean, out_p50, writes_mean, writes_p50 = found[-1]
    work = {"mean": float(mean), "p50": float(p50), "p99": float(p99), "steps": float(steps)}
    if p999:
        work.update(p99_9=float(p999), max=float(most))
    if out_mean:
        work.update(out_mean=float(out_mean), out_p50=float(out_p50))
    if writes_mean:
        work.update(writes_mean=float(writes_mean), writes_p50=float(writes_p50))
    return work
