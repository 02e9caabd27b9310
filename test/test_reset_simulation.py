"""The simulator's reset_simulation service (std_srvs/srv/Empty, as gazebo_ros names it): back to the initial
state with the parameters as they are. The policy without DDS (``SimulatorStepper.reset``; the controller's
``StateAnswerer.restart`` when its states go back in time), then the nodes: a run, the service called mid-run,
the run again, and the second run's joint_states equal the first's byte for byte."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import node_params
from ros_helpers import REPO_ROOT, isolated_env, node_argv, params_file, start
from test_answering import Q0, answerer, no_reports
from test_stepping import U, receiving, snapshot, stepper

from bracing_core.answering import Answer
from bracing_core.stepping import SimulatorStepper, StateOut, StepOut

PEER = str(REPO_ROOT / "test" / "reset_peer.py")
NOISY = {"sensors.position_noise_rad": 1e-4, "sensors.velocity_filter_hz": 200.0, "sensors.current_noise_a": 0.01}
"""Sensors whose noise and filter run on: a reset must start them again too."""


def out_bytes(value: Any) -> Any:
    """What a state or step report carries, bit for bit (arrays as bytes, nested)."""
    if isinstance(value, np.ndarray):
        return value.tobytes()
    if isinstance(value, (list, tuple)):
        return [out_bytes(v) for v in value]
    return value


def state_bytes(state: StateOut) -> Any:
    return out_bytes([state.t_ns, state.position, state.velocity, state.effort, state.measured])


def step_bytes(step: StepOut) -> Any:
    fields = (step.active, step.wrenches, step.voltage, step.current, step.true_current, step.power, step.energies)
    return out_bytes([step.t_ns, *fields, step.temperature])


def run_lockstep(core: SimulatorStepper, clock: Any, steps: int) -> None:
    """``steps`` lockstep steps, each answered with a command of its own (the same ones on every run)."""
    for k in range(steps):
        core.step_lockstep(receiving(core, clock, [(core.now_ns, U * (1.0 + 0.05 * k))]))


def test_a_reset_goes_back_to_the_initial_state_and_the_run_repeats_bit_for_bit() -> None:
    core, log, outlet, clock = stepper(NOISY, initial_current="steady")
    start_state = snapshot(core)
    core.send_state()
    run_lockstep(core, clock, 40)
    first_states, first_steps, end = outlet.states[:], outlet.steps[:], snapshot(core)
    waited_for = core.now_ns
    outlet.states.clear(), outlet.steps.clear()
    core.reset()
    assert snapshot(core) == start_state and core.now_ns == 0  # the engine, the contacts and the sim clock
    assert [s.t_ns for s in outlet.states] == [0]  # the initial state goes out again: the controller sees it
    assert "reset_simulation: back to the initial state at t = 0.000000 s" in log.lines
    core.offer(waited_for, U, False)  # the answer to the state the reset stopped waiting for: dropped quietly
    assert core.pending == {} and not log.reports
    run_lockstep(core, clock, 40)
    assert snapshot(core) == end
    assert [state_bytes(s) for s in outlet.states] == [state_bytes(s) for s in first_states]  # noise too
    assert [step_bytes(s) for s in outlet.steps] == [step_bytes(s) for s in first_steps]
    assert not log.reports  # nothing refused, nothing stale


def test_a_reset_before_the_first_state_sends_nothing() -> None:
    core, _, outlet, _ = stepper()
    start_state = snapshot(core)
    core.reset()
    assert snapshot(core) == start_state and outlet.states == []


def test_a_reset_in_real_time_restarts_the_pace_and_the_held_command() -> None:
    core, _, outlet, clock = stepper(stepping="real_time")
    core.start_real_time()
    core.offer(0, U, False)
    for _ in range(5):
        clock.now += core.config.step
        core.tick()
    clock.now += 3.0
    core.reset()
    assert core.latest_command is None and core.sim.steps_taken == 0
    assert outlet.states[-1].t_ns == 0 and np.array_equal(core.command, np.zeros(4))
    clock.now += 2.0
    core.tick()
    core.finish_real_time()
    assert core.real_time_achieved == pytest.approx(core.sim.time / 2.0)  # the pace from the reset, not the start


def answer_run(core: Any, states: list[tuple[int, np.ndarray, np.ndarray]]) -> list[Answer]:
    sent: list[Answer] = []
    for stamp, q, dq in states:
        core.answer(stamp, q, dq, no_reports, sent.append)
    return sent


def test_states_back_in_time_start_the_controller_again_with_its_parameters_as_they_are() -> None:
    # An integral term (hand.ki) and the hand's first measured position: what a new run must forget.
    ctl = {"hand.ki": [400.0, 400.0]}
    core, log, _, _ = answerer(ctl)
    states = [(k * 1_000_000, Q0 + 0.002 * k, np.full(4, 0.1)) for k in range(30)]
    answer_run(core, states)
    values = node_params("bracing_controller", own=ctl)
    assert core.retune(dict(values), [("hand.kp", [250.0, 250.0])]) is None  # applied from the next state on
    again = answer_run(core, states)
    assert any("joint_states went back in time, from t = 0.029000 s to 0.000000 s" in line for line in log.lines)
    fresh, _, _, _ = answerer({**ctl, "hand.kp": [250.0, 250.0]})
    expected = answer_run(fresh, states)
    assert [a.output.command.tobytes() for a in again] == [a.output.command.tobytes() for a in expected]
    assert [a.output.hand_desired.tobytes() for a in again] == [a.output.hand_desired.tobytes() for a in expected]
    assert core.answered_ns == states[-1][0]


def test_the_controller_without_the_restart_would_answer_otherwise() -> None:
    # The test above can fail: the same states answered again without the restart give other commands.
    ctl = {"hand.ki": [400.0, 400.0]}
    core, _, _, _ = answerer(ctl)
    states = [(k * 1_000_000, Q0 + 0.002 * k, np.full(4, 0.1)) for k in range(30)]
    first = answer_run(core, states)
    core.restart = lambda stamp_ns: None  # type: ignore[method-assign]
    again = answer_run(core, states)
    assert [a.output.command.tobytes() for a in again] != [a.output.command.tobytes() for a in first]


# --------------------------------------------------------------------------- the nodes


def test_reset_simulation_mid_run_repeats_the_run_byte_for_byte(tmp_path: Path) -> None:
    duration, reset_at = 1.0, 0.2  # [s] of sim time; the service is served between steps, every 100th
    urdf = str(REPO_ROOT / "config" / "paper_4link.urdf")
    # wait_for_reset: a reset that comes after the run's end (the peer, on a loaded machine, behind the pair)
    # is served too, and repeats the run as one mid-run does.
    sim = {"duration": duration, "min_subscribers": 2, "wait_for_recorder": False, "robot.urdf": urdf}
    sim["wait_for_reset"] = True
    ctl = {"wait_for_recorder": False, "robot.urdf": urdf, "hand.ki": [400.0, 400.0]}
    env = isolated_env()
    out = tmp_path / "states.json"
    peer = start([sys.executable, PEER, "--reset-at", str(reset_at), "--duration", str(duration), str(out)], env)
    controller = start(node_argv("bracing_controller.node", params_file(tmp_path, "bracing_controller", ctl)), env)
    simulator = start(node_argv("bracing_sim.node", params_file(tmp_path, "bracing_simulator", sim)), env)
    try:
        peer.wait(timeout=240)
    except subprocess.TimeoutExpired:
        pass  # the first assert below says so, with every process's output
    finally:
        peer_log, sim_log, ctl_log = (stopped(p) for p in (peer, simulator, controller))
    assert peer.returncode == 0, f"{peer_log}\n--- simulator\n{sim_log[-3000:]}\n--- controller\n{ctl_log[-3000:]}"
    assert simulator.returncode == 0, sim_log[-3000:]  # stopped by SIGINT, as wait_for_reset says
    states = [(stamp, bytes.fromhex(data)) for stamp, data in json.loads(out.read_text())["states"]]
    stamps = [stamp for stamp, _ in states]
    back = next(k for k in range(1, len(stamps)) if stamps[k] < stamps[k - 1])  # where time went back
    first, second = states[:back], states[back:]
    assert stamps[back] == 0 and stamps[back - 1] >= reset_at * 1e9 and stamps[back - 1] % 100_000_000 == 0
    assert len(second) == round(duration / 0.001) + 1  # the whole run again, to its end
    assert second[: len(first)] == first  # every state, its bytes: position, velocity, effort, stamp
    assert "reset_simulation: back to the initial state at t = 0.000000 s" in sim_log
    assert "joint_states went back in time" in ctl_log
    assert "rejected" not in sim_log and "watchdog" not in sim_log  # every answer in time, none stale


def stopped(process: subprocess.Popen[str]) -> str:
    """``process``'s output once it has ended: asked to (SIGINT), then killed if it does not within 30 s."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        return process.communicate(timeout=30)[0]
    except subprocess.TimeoutExpired:
        process.kill()
        return process.communicate()[0]
