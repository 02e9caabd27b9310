"""A long lockstep run of the two node processes: no memory growth, no residual drift."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import PAPER_YAML
from ros_helpers import REPO_ROOT, isolated_env

SIM_SECONDS = float(os.environ.get("BRACING_LONG_RUN_SECONDS", "600"))
PROGRESS = re.compile(r"progress t=([0-9.]+) max_residual=([0-9.eE+-]+)")


def _rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError("no VmRSS")


@pytest.mark.slow
def test_ten_minutes_of_lockstep_without_growth_or_drift(tmp_path: Path) -> None:
    env = isolated_env()
    extra = tmp_path / "long.yaml"
    extra.write_text(f"bracing_simulator:\n  ros__parameters:\n    duration: {SIM_SECONDS}\n")
    args = ["--ros-args", "--params-file", str(PAPER_YAML), "--params-file", str(extra)]
    sim_log = tmp_path / "sim.log"
    controller = subprocess.Popen(
        [sys.executable, "-m", "bracing_controller.node", *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        cwd=REPO_ROOT,
    )
    with sim_log.open("w") as log:
        sim = subprocess.Popen(
            [sys.executable, "-m", "bracing_sim.node", *args],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            cwd=REPO_ROOT,
        )
    samples: list[tuple[float, int, int]] = []  # (sim time, sim RSS, controller RSS)
    try:
        while sim.poll() is None:
            time.sleep(2.0)
            found = PROGRESS.findall(sim_log.read_text())
            if found and sim.poll() is None:
                samples.append((float(found[-1][0]), _rss_kib(sim.pid), _rss_kib(controller.pid)))
            assert controller.poll() is None, "the controller died"
    finally:
        controller.terminate()
        controller.wait(20)
        if sim.poll() is None:
            sim.kill()
    assert sim.returncode == 0, sim_log.read_text()[-3000:]
    progress = PROGRESS.findall(sim_log.read_text())
    assert float(progress[-1][0]) == pytest.approx(SIM_SECONDS)
    residuals = [float(r) for _, r in progress]
    print(f"max |residual| over {SIM_SECONDS:g} s: {residuals[-1]:.3e} m")
    assert residuals[-1] < 1e-9  # no drift of the constraint (Baumgarte off, as in the paper)
    warm = [s for s in samples if s[0] >= 0.1 * SIM_SECONDS]
    assert len(warm) >= 5, samples
    for column, name in ((1, "simulator"), (2, "controller")):
        base, peak = warm[0][column], max(s[column] for s in warm)
        print(f"{name} RSS after warm-up {base} KiB, peak {peak} KiB")
        assert peak <= 1.05 * base, f"{name} memory grew from {base} to {peak} KiB"
