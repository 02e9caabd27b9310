"""Bad input never crashes a node, never reaches the integrator, and loses nothing."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import PAPER_YAML, build_scenario
from lockstep_driver import JOINTS, known_command
from ros_helpers import (
    CONTROLLER_PATHS,
    DRIVER,
    PATH_LINES,
    REPO_ROOT,
    SIMULATOR_PATH_LINES,
    SIMULATOR_PATHS,
    NodeProcess,
    drive,
    isolated_env,
    node_argv,
    pair_argv,
    params_file,
    run,
    start,
)

from bracing_controller.rcl_path import PATH_ENV
from bracing_core.dynamics import InputMode
from bracing_ros.commands import CommandError, command_vector
from bracing_sim.rcl_path import PATH_ENV as SIMULATOR_PATH_ENV


def _drive(
    tmp_path: Path, overrides: dict[str, object], driver_args: list[str], path: str = "rcl"
) -> tuple[list[dict], str]:
    """The lockstep driver against a simulator taking motor_command on ``path`` (``SIMULATOR_PATHS``)."""
    extra = params_file(tmp_path, "bracing_simulator", overrides)
    env = {SIMULATOR_PATH_ENV: path}
    driver, node, log = drive(node_argv("bracing_sim.node", extra), driver_args, wait_for_node=True, **env)
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    assert node.returncode == 0, log  # it finished by itself
    assert SIMULATOR_PATH_LINES[path] in log, log
    return json.loads(driver.stdout.strip().splitlines()[-1])["states"], log


def _reference(commands: list[np.ndarray], limit: float = 0.0) -> list[np.ndarray]:
    sim = build_scenario(with_controller=False).sim
    positions = [sim.position]
    for u in commands:
        sim.step(np.clip(u, -limit, limit) if limit else u)
        positions.append(sim.position)
    return positions


def read_counts(log: str) -> tuple[int, int]:
    """The commands the simulator's C++ path read, and those it handed to the Python path (its last log line)."""
    found = re.search(r"motor_command path: (\d+) read in C\+\+ on rcl, (\d+) by the Python path", log)
    assert found is not None, log
    return int(found[1]), int(found[2])


@pytest.mark.parametrize("path", SIMULATOR_PATHS)
def test_malformed_commands_are_rejected_and_never_integrated(tmp_path: Path, path: str) -> None:
    """Each malformed command refused with its reason on both paths: on the C++ path every one of the 10 a state
    that are no command or not the template's layout (the driver's valid ones name the joints shuffled) is
    handed to the Python path, which says why."""
    steps = 40
    states, log = _drive(tmp_path, {"duration": (steps - 1) * 1e-3}, ["sim-bad", str(steps)], path)
    reference = _reference([np.asarray(known_command(k)) for k in range(steps - 1)])
    assert len(states) == steps
    for state, expected in zip(states, reference, strict=True):
        np.testing.assert_allclose(state["position"], expected, rtol=0, atol=1e-12)
    for reason in (
        "non-finite values",
        "1 names but",
        "missing ['joint4']",
        "unknown ['joint9']",
        "duplicate joint names",
        "configured for voltage",
        "mode unknown (7)",
        "is stale",
        "from the future",
        "Invalid sequence length 4",  # the first bytes that are no command (the rest: same kind)
    ):
        assert reason in log or reason.replace("1 names", "4 names") in log, reason
    if path == "rcl":
        read, handed_over = read_counts(log)
        assert handed_over >= 11 * (steps - 1), (read, handed_over)


@pytest.mark.parametrize("path", SIMULATOR_PATHS)
def test_over_limit_commands_are_saturated(tmp_path: Path, path: str) -> None:
    steps, scale, limit = 30, 50.0, 5.0
    states, log = _drive(
        tmp_path,
        {"duration": (steps - 1) * 1e-3, "motors.voltage_limit": limit},
        ["sim-scale", str(steps), str(scale)],
        path,
    )
    reference = _reference([scale * np.asarray(known_command(k)) for k in range(steps - 1)], limit)
    for state, expected in zip(states, reference, strict=True):
        np.testing.assert_allclose(state["position"], expected, rtol=0, atol=1e-12)
    assert "saturated to +/-5.0" in log


@pytest.mark.parametrize("path", SIMULATOR_PATHS)
@pytest.mark.parametrize("policy", ["hold", "zero"])
def test_lockstep_watchdog_applies_its_policy(tmp_path: Path, policy: str, path: str) -> None:
    steps, skipped = 20, 7
    states, log = _drive(
        tmp_path,
        {"duration": (steps - 1) * 1e-3, "command_timeout": 0.3, "watchdog_policy": policy},
        ["sim-skip", str(steps), str(skipped)],
        path,
    )
    commands = [np.asarray(known_command(k)) for k in range(steps - 1)]
    commands[skipped] = commands[skipped - 1] if policy == "hold" else np.zeros(4)
    for state, expected in zip(states, _reference(commands), strict=True):
        np.testing.assert_allclose(state["position"], expected, rtol=0, atol=1e-12)
    assert "no valid motor_command" in log


def test_command_vector_matches_by_name_and_validates() -> None:
    u, saturated = command_vector(["b", "a"], [2.0, 1.0], 0, ["a", "b"], InputMode.VOLTAGE)
    assert u.tolist() == [1.0, 2.0] and not saturated
    u, saturated = command_vector(["a", "b"], [20.0, -30.0], 1, ["a", "b"], InputMode.TORQUE, limit=10.0)
    assert u.tolist() == [10.0, -10.0] and saturated
    for names, values, mode in (
        (["a"], [1.0], 0),
        (["a", "a"], [1.0, 1.0], 0),
        (["a", "b"], [1.0], 0),
        (["a", "b"], [np.nan, 1.0], 0),
        (["a", "b"], [1.0, 1.0], 1),
        (["a", "c"], [1.0, 1.0], 0),
    ):
        with pytest.raises(CommandError):
            command_vector(names, values, mode, ["a", "b"], InputMode.VOLTAGE)


@pytest.mark.parametrize("path", CONTROLLER_PATHS)
def test_controller_ignores_malformed_joint_states(tmp_path: Path, path: str) -> None:
    """On each of the controller's per-state paths (the states in the simulator's layout, efforts and all: the
    C++ path reads them itself)."""
    position = (np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi).tolist()
    good = {"name": JOINTS, "position": position, "velocity": [0.0] * 4, "effort": [0.0] * 4}
    inputs = [
        good,
        {**good, "name": JOINTS[:3], "position": good["position"][:3], "velocity": [0.0] * 3},
        {**good, "position": [float("nan"), *good["position"][1:]]},
        {**good, "velocity": [0.0] * 3},
        {"raw_hex": "00010000" + "ff" * 40},  # no JointState at all
        good,
    ]
    states_file = tmp_path / "states.json"
    states_file.write_text(json.dumps(inputs))
    argv = node_argv("bracing_controller.node")
    driver, node, log = drive(argv, ["controller", str(states_file)], **{PATH_ENV: path})
    assert PATH_LINES[path] in log, log[-3000:]
    assert node.returncode in (0, -15), "the controller died"  # stopped by the test, not by the input
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    answers = json.loads(driver.stdout.strip().splitlines()[-1])["answers"]
    assert answers[0] is not None and answers[5] is not None
    assert answers[1] is None and answers[2] is None and answers[3] is None and answers[4] is None
    assert "missing joints ['joint4']" in log and "non-finite" in log and "3 velocities" in log
    assert "joint_states ignored: not a sensor_msgs/msg/JointState: Invalid string length" in log


@pytest.mark.parametrize("path", SIMULATOR_PATHS)
@pytest.mark.parametrize("policy", ["hold", "zero"])
def test_a_command_whose_step_is_not_finite_is_rejected_and_the_run_goes_on(
    tmp_path: Path, policy: str, path: str
) -> None:
    """1e300 V on every joint is finite and well-formed, but its step overflows: it is rejected
    like a malformed command (naming the joint and value), the state is not advanced on it,
    the watchdog's policy applies, and the run goes on to its end."""
    steps, absurd = 20, 6
    states, log = _drive(
        tmp_path,
        {"duration": (steps - 1) * 1e-3, "command_timeout": 0.3, "watchdog_policy": policy},
        ["sim-absurd", str(steps), str(absurd)],
        path,
    )
    commands = [np.asarray(known_command(k)) for k in range(steps - 1)]
    commands[absurd] = commands[absurd - 1] if policy == "hold" else np.zeros(4)
    assert len(states) == steps
    for state, expected in zip(states, _reference(commands), strict=True):
        assert np.isfinite(state["effort"]).all()
        np.testing.assert_allclose(state["position"], expected, rtol=0, atol=1e-12)
    assert "would not be finite (joint1 = 1e+300 V" in log, log
    assert "no valid motor_command for t = 0.006000 s" in log


def test_pair_reports_divergence_and_keeps_the_bag(tmp_path: Path) -> None:
    config = tmp_path / "scenario.yaml"
    text = PAPER_YAML.read_text().replace(
        "urdf: paper_4link.urdf", f"urdf: {REPO_ROOT / 'config' / 'paper_4link.urdf'}"
    )
    config.write_text(text.replace("divergence_residual: 0.01", "divergence_residual: 1.0e-30"))
    done = run(pair_argv(tmp_path / "run", config=config), timeout=120)
    assert done.returncode == 3, done.stdout + done.stderr  # a divergence (test_failures: its summary and hint)
    assert "simulation diverged at t = " in done.stderr and "divergence_residual" in done.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "failed" and "divergence_residual" in summary["error"]
    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "run" / "bag"]) as reader:
        assert any(c.topic == "/joint_states" for c in reader.connections)


def test_real_time_mode_zeroes_a_stale_command(tmp_path: Path) -> None:
    """Real-time stepping holds the latest command; once the controller falls silent for
    command_timeout, the simulator applies zero (with a warning) and keeps time. The run lasts until
    the warning came (the driver answers 50 states, then stops): the watchdog's promise is a silence of
    command_timeout on the simulator's clock, however long a loaded machine takes to answer the 50
    (a fixed 3 s run once saw the 50 answers spread over all of it, and no warning)."""
    overrides = {"stepping": "real_time", "duration": 0.0, "command_timeout": 0.05}
    argv = node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", overrides))
    env = isolated_env()
    node = NodeProcess(start(argv, env))
    try:
        driver_argv = [sys.executable, DRIVER, "sim", "50"]
        driver = subprocess.run(driver_argv, env=env, capture_output=True, text=True, timeout=180)
        assert driver.returncode == 0, driver.stdout + driver.stderr + node.text()
        answered = json.loads(driver.stdout)["states"]
        warned = node.wait_for("motor_command stale: applying zero", 60.0)
        assert warned, node.text()[-3000:]
        stepped_on = node.wait_for("progress t=", 60.0, after=warned)  # it kept time after the warning
    finally:
        code = node.stop()
    log = node.text()
    assert code == 0, log[-3000:]
    assert stepped_on, log[-3000:]
    last_answered = answered[-1]["stamp"][0] + answered[-1]["stamp"][1] * 1e-9  # the silence began after this
    warned_at = float(re.findall(r"first at t = ([0-9.]+) s", warned)[0])
    assert last_answered < warned_at < float(re.findall(r"progress t=([0-9.]+)", stepped_on)[0]), (warned, stepped_on)
