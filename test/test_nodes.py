"""The nodes over DDS agree exactly with the core called in-process."""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path

import numpy as np
from conftest import PAPER_YAML, build_scenario, node_params
from lockstep_driver import JOINTS, known_command
from ros_helpers import REPO_ROOT, drive, isolated_env, node_argv, params_file, run

from bracing_core.controller_config import ControllerConfig
from bracing_core.law import DecoupledController
from bracing_core.rcl_yaml import load_params_file


def _run_node(module: str, node: str, overrides: dict[str, object], driver_args: list[str], tmp_path: Path) -> dict:
    driver, _, log = drive(node_argv(module, params_file(tmp_path, node, overrides)), driver_args)
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    return json.loads(driver.stdout.strip().splitlines()[-1])


def test_simulator_node_in_lockstep_matches_core(tmp_path: Path) -> None:
    """Driven with a known voltage sequence (joint names shuffled in every command), the node's
    joint states equal the core Simulator stepped directly with the same inputs, to 1e-12."""
    steps = 300
    result = _run_node(
        "bracing_sim.node", "bracing_simulator", {"duration": (steps - 1) * 0.001}, ["sim", str(steps)], tmp_path
    )
    states = result["states"]
    assert len(states) == steps
    sim = build_scenario(with_controller=False).sim
    for k, state in enumerate(states):
        assert state["name"] == JOINTS
        assert state["stamp"] == [0, k * 1_000_000]
        np.testing.assert_allclose(state["position"], sim.position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(state["velocity"], sim.velocity, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            state["effort"], sim.evaluate(np.asarray(known_command(k))).effort, rtol=0, atol=1e-9
        )
        if k + 1 < steps:
            sim.step(np.asarray(known_command(k)))
    assert np.ptp([s["position"] for s in states], axis=0).max() > 1e-3  # the inputs did move the arm


def test_controller_node_publishes_the_core_command(tmp_path: Path) -> None:
    """Fed states (names shuffled), the node answers each with exactly the core law's command."""
    rng = np.random.default_rng(7)
    q0 = np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi
    order = [2, 0, 3, 1]
    inputs = []
    for _ in range(40):
        q, dq = q0 + rng.normal(0, 0.05, 4), rng.normal(0, 0.3, 4)
        inputs.append(
            {"name": [JOINTS[j] for j in order], "position": q[order].tolist(), "velocity": dq[order].tolist()}
        )
    states_file = tmp_path / "states.json"
    states_file.write_text(json.dumps(inputs))
    answers = _run_node(
        "bracing_controller.node", "bracing_controller", {}, ["controller", str(states_file)], tmp_path
    )["answers"]
    law = DecoupledController(ControllerConfig.from_params(node_params("bracing_controller"), [REPO_ROOT / "config"]))
    for k, (state, answer) in enumerate(zip(inputs, answers, strict=True)):
        assert answer is not None, f"no command for state {k}"
        assert answer["mode"] == 0 and answer["name"] == JOINTS
        q, dq = np.empty(4), np.empty(4)
        q[order], dq[order] = state["position"], state["velocity"]
        expected = law.update(k * 1e-3, q, dq).command
        np.testing.assert_allclose(answer["value"], expected, rtol=0, atol=1e-12)


def test_node_refuses_bad_configuration_with_one_clear_line(tmp_path: Path) -> None:
    extra = params_file(tmp_path, "bracing_simulator", {"motors.resistance": [0.6, 0.6, 0.6]})
    done = run(node_argv("bracing_sim.node", extra))
    assert done.returncode == 2
    assert "motors.resistance: expected 4 values" in done.stderr
    assert "Traceback" not in done.stderr + done.stdout


def test_infeasible_start_is_refused_naming_the_contact(tmp_path: Path) -> None:
    params = load_params_file(PAPER_YAML, "bracing_simulator")
    q = list(params["initial_position"])
    q[1] += 0.1  # lifts the elbow off the floor
    done = run(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", {"initial_position": q})))
    assert done.returncode == 2
    assert "contact 'elbow'" in done.stderr and "off its plane" in done.stderr


def test_nodes_stop_on_sigint_even_when_started_with_it_ignored() -> None:
    """bracing-pair stops the nodes with SIGINT. A script's background job (nohup, `cmd &`)
    starts them with SIGINT ignored; they must still stop on it (cleanly: exit 0), at once."""
    env = isolated_env()
    for module in ("bracing_controller.node", "bracing_sim.node"):
        node = subprocess.Popen(
            node_argv(module),
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=REPO_ROOT,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
        )
        try:
            assert node.stdout is not None
            # Configured: the controller waits for the recorder, the simulator for its subscribers.
            while "voltage" not in (line := node.stdout.readline()):
                assert line, f"{module} exited before it was configured"
            node.send_signal(signal.SIGINT)
            assert node.wait(timeout=10.0) == 0, module
        finally:
            node.kill()
            node.wait()
