"""Slow checks of what a user relies on most: runs at once never lose a message or cross, and
``make run`` passes round after round, also with two clones running it at once.

    make test-slow            (or: python -m pytest test/test_dependability.py -m slow -s)

``BRACING_STRESS_ROUNDS`` / ``BRACING_STRESS_SECONDS`` and ``BRACING_MAKE_RUN_ROUNDS`` shorten them.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from ros_helpers import REPO_ROOT

ROUNDS = int(os.environ.get("BRACING_STRESS_ROUNDS", "10"))
SECONDS = float(os.environ.get("BRACING_STRESS_SECONDS", "10"))
MAKE_RUN_ROUNDS = int(os.environ.get("BRACING_MAKE_RUN_ROUNDS", "10"))


@pytest.mark.slow
def test_three_pairs_at_once_round_after_round(tmp_path: Path) -> None:
    """3 bracing-pair runs at once on 2 cores, ROUNDS rounds: every bag complete, every summary
    equal to the same run done alone (tools/stress_pairs.py, which docs/concepts/dependability.md names)."""
    argv = [sys.executable, str(REPO_ROOT / "tools" / "stress_pairs.py"), "--runs", "3"]
    argv += ["--rounds", str(ROUNDS), "--duration", str(SECONDS), "--output", str(tmp_path)]
    done = subprocess.run(argv, cwd=REPO_ROOT, capture_output=True, text=True, timeout=3600)
    print(done.stdout)
    assert done.returncode == 0, done.stdout[-5000:] + done.stderr[-3000:]
    assert f"{3 * ROUNDS} of {3 * ROUNDS} runs complete and equal to a run done alone" in done.stdout


def _clone(tmp_path: Path, name: str) -> Path:
    """A fresh clone of this repository's committed main, with ../shared beside it as CI has."""
    clone = tmp_path / name / "main"
    subprocess.run(["git", "clone", "--quiet", str(REPO_ROOT), str(clone)], check=True, timeout=300)
    shared = REPO_ROOT.parent / "shared"
    if shared.exists():
        (clone.parent / "shared").symlink_to(shared)
    return clone


def _energy_ratio(output: str) -> float:
    found = re.findall(r"energy ratio braced / free space: ([0-9.]+)", output)
    assert found, output[-3000:]
    return float(found[-1])


def _make_run(clone: Path) -> subprocess.Popen[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VIRTUAL_ENV", "AMENT", "COLCON", "ROS_"))}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if ".venv" not in p)
    return subprocess.Popen(
        ["make", "run"], cwd=clone, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


@pytest.mark.slow
def test_make_run_from_a_fresh_clone_passes_round_after_round(tmp_path: Path) -> None:
    clone = _clone(tmp_path, "one")
    ratios = []
    for round_no in range(1, MAKE_RUN_ROUNDS + 1):
        run = _make_run(clone)
        output = run.communicate(timeout=1800)[0]
        assert run.returncode == 0, f"round {round_no}:\n{output[-5000:]}"
        ratios.append(_energy_ratio(output))
        print(f"make run round {round_no}: exit 0, energy ratio {ratios[-1]}", flush=True)
    assert len(set(ratios)) == 1, ratios  # lockstep: the same numbers every time


@pytest.mark.slow
def test_two_make_runs_at_once_in_two_clones(tmp_path: Path) -> None:
    clones = [_clone(tmp_path, name) for name in ("a", "b")]
    for clone in clones:  # set up one after the other (pip and colcon), then run both together
        setup = subprocess.run(["make", "setup"], cwd=clone, capture_output=True, text=True, timeout=1800)
        assert setup.returncode == 0, setup.stdout[-3000:] + setup.stderr[-3000:]
    runs = [_make_run(clone) for clone in clones]
    outputs = [run.communicate(timeout=1800)[0] for run in runs]
    for run, output in zip(runs, outputs, strict=True):
        assert run.returncode == 0, output[-5000:]
    assert _energy_ratio(outputs[0]) == _energy_ratio(outputs[1])
