"""A run that fails before its first step leaves nothing behind but its logs, and the same
--output works again (the retry used to be refused, "--output: out/volt/bag exists
already", and the folder held an empty bag, overrides, a timeline)."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

from ros_helpers import isolated_env, pair_argv, run, start


def _kill_at_start(pattern: str, timeout: float = 60.0) -> None:
    """SIGKILL the process whose command line matches ``pattern`` as soon as it exists: a node dying
    at start-up (a crash, the OOM killer) long before its imports end (~1 s), so before any step."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if subprocess.run(["pkill", "-KILL", "-f", pattern], capture_output=True).returncode == 0:
            return
        time.sleep(0.01)
    raise AssertionError(f"no process matched {pattern}")


def test_a_run_that_dies_before_its_first_step_keeps_only_its_logs_and_runs_again(tmp_path: Path) -> None:
    output = tmp_path / "volt"
    proc = start(pair_argv(output, "--duration", "0.2", "--no-animation"), isolated_env())
    try:
        _kill_at_start(f"bracing_controller.node.*{output}")
        out = proc.communicate(timeout=120)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, out
    assert "controller exited" in out and "nothing of it was kept but its logs" in out
    assert sorted(p.name for p in output.iterdir()) == ["logs"]  # no bag, params or timeline
    assert "lockstep: stepping" not in (output / "logs" / "simulator.log").read_text()

    again = run(pair_argv(output, "--duration", "0.2", "--no-animation"), timeout=240)
    assert again.returncode == 0, again.stdout + again.stderr
    assert (output / "bag").is_dir() and (output / "summary.json").is_file()
