"""Helpers for tests that run real ROS 2 processes: DDS isolation, node command lines, processes."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bracing_bringup.domains import hold_domain

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER_YAML = REPO_ROOT / "config" / "paper_4link.yaml"
DRIVER = str(REPO_ROOT / "test" / "lockstep_driver.py")


_held = contextlib.ExitStack()


def hold_test_domain() -> int:
    """A ROS domain id held by this test process until the current test ends (``release_domains``).

    The same coordination as bracing-pair's (``bracing_bringup.domains``): two test runs, or a
    test and a user's run, on one machine never share a domain.
    """
    return _held.enter_context(hold_domain()).domain_id


def release_domains() -> None:
    _held.close()


CONTROLLER_PATHS = ("rcl", "python")
"""The controller node's per-state paths (bracing_controller.rcl_path: the C++ one on rcl, the Python one),
chosen by the environment variable BRACING_CONTROLLER_PATH."""
PATH_LINES = {"rcl": "per-state path: C++ on rcl", "python": "per-state path: Python (BRACING_CONTROLLER_PATH=python)"}
"""What the controller logs of the path it takes."""
SIMULATOR_PATHS = ("rcl", "python")
"""The simulator's motor_command paths (bracing_sim.rcl_path: read in C++ on rcl, or by the Python path), chosen
by the environment variable BRACING_SIMULATOR_PATH."""
SIMULATOR_PATH_LINES = {
    "rcl": "motor_command path: C++ on rcl",
    "python": "motor_command path: Python (BRACING_SIMULATOR_PATH=python)",
}
"""What the simulator logs of the path it takes."""


def isolated_env(domain_id: int | None = None, **extra: str) -> dict[str, str]:
    """Environment for a child ROS process: localhost-only discovery, a domain of its own
    (held by this process until the test ends)."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id if domain_id is not None else hold_test_domain())
    env["PYTHONUNBUFFERED"] = "1"
    env.update(extra)
    return env


def params_file(tmp_path: Path, node: str, params: dict[str, Any]) -> Path:
    """A params file with one node's section, to pass after the scenario file (it wins)."""
    path = tmp_path / f"{node}.yaml"
    path.write_text(yaml.safe_dump({node: {"ros__parameters": params}}))
    return path


def node_argv(module: str, *params_files: Path) -> list[str]:
    """``python -m module --ros-args --params-file ...`` (the paper scenario first)."""
    argv = [sys.executable, "-m", module, "--ros-args", "--params-file", str(PAPER_YAML)]
    for path in params_files:
        argv += ["--params-file", str(path)]
    return argv


def start(argv: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
    """A child process with its output (stdout and stderr) in one pipe."""
    return subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO_ROOT)


def run(argv: list[str], env: dict[str, str] | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    """Run to completion in an isolated domain, capturing stdout and stderr apart. Past ``timeout`` the
    process is asked for every thread's stack (SIGUSR1: faulthandler in bracing-pair, the nodes and the
    recorder), killed, and the test fails with what it printed: a hang says where it hung."""
    process = subprocess.Popen(
        argv, env=env or isolated_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO_ROOT
    )
    try:
        stdout, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGUSR1)
        time.sleep(2.0)
        process.kill()
        stdout, stderr = process.communicate()
        raise AssertionError(
            f"{argv[:3]} did not finish in {timeout:g} s; its output, then its threads' stacks:\n"
            f"{stdout[-5000:]}\n{stderr[-20000:]}"
        ) from None
    return subprocess.CompletedProcess(argv, process.returncode, stdout, stderr)


@dataclass
class NodeProcess:
    """A node process and its output lines, each with its arrival time (monotonic)."""

    process: subprocess.Popen[str]
    lines: list[tuple[float, str]] = field(default_factory=list)
    interrupted: bool = False  # SIGINT sent (once: a second would interrupt its stop)

    def __post_init__(self) -> None:
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append((time.monotonic(), line))

    def text(self) -> str:
        return "".join(line for _, line in self.lines)

    def wait_for(self, words: str, timeout: float, after: str | None = None) -> str | None:
        """The first line with ``words`` (after the line ``after``, if given) within ``timeout`` [s]."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            lines = [line for _, line in list(self.lines)]
            if after is not None:
                lines = lines[lines.index(after) + 1 :] if after in lines else []
            for line in lines:
                if words in line:
                    return line
            time.sleep(0.05)
        return None

    def between(self, words: str, since: float, until: float) -> list[str]:
        return [line for t, line in list(self.lines) if since <= t <= until and words in line]

    def interrupt(self) -> None:
        if not self.interrupted and self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        self.interrupted = True

    def stop(self) -> int:
        self.interrupt()
        try:
            self.process.wait(30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(10)
        self._reader.join(10)
        return self.process.returncode


def drive(
    node: list[str],
    driver_args: list[str],
    wait_for_node: bool = False,
    driver_timeout: str | None = None,
    **extra_env: str,
) -> tuple[subprocess.CompletedProcess[str], subprocess.Popen[str], str]:
    """Start a node (``extra_env`` in its environment) and run the lockstep driver against it in the same domain.

    Returns the driver's result, the node process and its log. With ``wait_for_node`` the
    node must finish by itself (else it is stopped once the driver is done).
    """
    env = isolated_env(**extra_env)
    process = start(node, env)
    try:
        driver_env = dict(env, DRIVER_TIMEOUT=driver_timeout) if driver_timeout else env
        driver = subprocess.run(
            [sys.executable, DRIVER, *driver_args], env=driver_env, capture_output=True, text=True, timeout=180
        )
        if wait_for_node:
            process.wait(60)
    finally:
        if process.poll() is None:
            process.terminate()
        log = process.communicate(timeout=20)[0]
    return driver, process, log


def pair_argv(output: Path, *extra: str, config: Path = PAPER_YAML) -> list[str]:
    """bracing-pair, quiet (it holds a domain of its own while it runs)."""
    return [
        sys.executable,
        "-m",
        "bracing_bringup.pair",
        "--config",
        str(config),
        "--output",
        str(output),
        "--quiet",
        *extra,
    ]


def bag_joint_positions(bag: Path) -> np.ndarray:
    """(N, n) the recorded /joint_states positions of a run's bag, in stamp order."""
    from rosbags.highlevel import AnyReader  # only the tests that read bags need it

    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/joint_states"]
        states = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections)]
    states.sort(key=lambda m: (m.header.stamp.sec, m.header.stamp.nanosec))
    return np.array([m.position for m in states])
