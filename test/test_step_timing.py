"""The nodes' per-step work (bracing_core.step_timing): waiting for the peer is not counted, and the
log line reads back as written (make bench's pair_step_breakdown_us reads it from the nodes' logs)."""

from __future__ import annotations

import pytest

from bracing_core import step_timing
from bracing_core.step_timing import WorkTimer, read_work_line


def test_the_mark_splits_the_work_at_the_answer_out(monkeypatch: pytest.MonkeyPatch) -> None:
    # begin 0, pause 2, resume 402 (a 400 us wait), mark 412 (the state out), end 450: 50 us of work,
    # 12 of them before the state was out, 8 of them in DDS writes.
    reads = iter([0.0, 2e-6, 402e-6, 412e-6, 450e-6])
    monkeypatch.setattr(step_timing.time, "perf_counter", lambda: next(reads))
    timer = WorkTimer()
    timer.begin()
    timer.pause()
    timer.resume()
    timer.mark()
    timer.end(written_s=8e-6)
    line = timer.line()
    assert line == (
        "per-step work [us]: mean 50.0, p50 50.0, p99 50.0, p99.9 50.0, max 50.0 over 1 steps; until the answer is"
        " out: mean 12.0, p50 12.0; DDS writes: mean 8.0, p50 8.0"
    )
    work = read_work_line(line)
    assert work == {
        "mean": 50.0, "p50": 50.0, "p99": 50.0, "p99_9": 50.0, "max": 50.0, "steps": 1.0, "out_mean": 12.0,
        "out_p50": 12.0, "writes_mean": 8.0, "writes_p50": 8.0,
    }  # fmt: skip


def test_the_wait_for_the_peer_is_not_work_and_the_line_reads_back(monkeypatch: pytest.MonkeyPatch) -> None:
    # Two steps on a clock read at begin, pause, resume, end: 10 us of work around a 500 us wait,
    # then 30 us with no wait.
    reads = iter([0.0, 4e-6, 504e-6, 510e-6, 1.0, 1.000030])
    monkeypatch.setattr(step_timing.time, "perf_counter", lambda: next(reads))
    timer = WorkTimer()
    assert timer.line() is None
    timer.begin()
    timer.pause()
    timer.resume()
    timer.end()
    timer.begin()
    timer.end()
    line = timer.line()
    # the tail: p99.9 between the two steps (numpy's linear interpolation), the maximum the slower step
    assert line == "per-step work [us]: mean 20.0, p50 20.0, p99 29.8, p99.9 30.0, max 30.0 over 2 steps"
    log = f"[INFO] [1.0] [bracing_simulator]: {line}\n[INFO] [1.1] [bracing_simulator]: finished at t = 1.0 s\n"
    assert read_work_line(log) == {"mean": 20.0, "p50": 20.0, "p99": 29.8, "p99_9": 30.0, "max": 30.0, "steps": 2.0}
    # a line without the tail (a log written before it was logged) still reads
    assert read_work_line("per-step work [us]: mean 20.0, p50 20.0, p99 29.8 over 2 steps") == {
        "mean": 20.0, "p50": 20.0, "p99": 29.8, "steps": 2.0,
    }  # fmt: skip
    assert read_work_line("finished at t = 1.0 s") is None


def test_a_step_timed_elsewhere_ends_when_it_says(monkeypatch: pytest.MonkeyPatch) -> None:
    # The controller's C++ path: begun at the take (20 us), ended at its return to the wait (35 us), with
    # the clock already at 900 us (the Python bookkeeping after several states): 15 us, not 880.
    monkeypatch.setattr(step_timing.time, "perf_counter", lambda: 900e-6)
    timer = WorkTimer()
    timer.begin(20e-6)
    timer.mark(30e-6)
    timer.end(at=35e-6)
    line = timer.line()
    assert line is not None and "p50 15.0" in line and "until the answer is out: mean 10.0" in line, line
