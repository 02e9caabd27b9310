"""Runs through reused processes: one simulator (``wait_for_reset``), one controller and one recorder
(``--stay``) make two runs of the pair's plan, the second begun by reset_simulation once the recorder has
opened its bag; the second bag equals the first, a fresh run's, message for message (the controller's
compute_time, a wall time, aside)."""

from __future__ import annotations

import queue
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from ros_helpers import PAPER_YAML, REPO_ROOT, isolated_env
from test_recorder_bag_switch import raw_bag, set_recorder
from test_recorder_report import Proc

from bracing_bringup.run_plan import PARAMS_FILE, RunOptions, plan_run, write_params
from bracing_core.overrides import SIMULATOR

DURATION_S = 0.3
RESET = """
import rclpy
from std_srvs.srv import Empty
rclpy.init()
node = rclpy.create_node("reused_runs_test")
client = node.create_client(Empty, "/reset_simulation")
assert client.wait_for_service(timeout_sec=30.0), "no reset_simulation"
future = client.call_async(Empty.Request())
rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
"""  # its response not required: Fast DDS drops one whose reader the server has not matched in 100 ms (the
# next bag, written, shows the reset was served)


def wrote(bag: Path) -> Callable[[str], bool]:
    """The recorder's line once it has closed ``bag``: "recorder wrote N messages to BAG"."""
    return lambda line: line.startswith("recorder wrote ") and line.endswith(f" messages to {bag}")


def wait_for(proc: Proc, wanted: Callable[[str], bool], timeout: float) -> str:
    """The first line of ``proc``'s output that is ``wanted`` (the test fails after ``timeout`` [s])."""
    try:
        while True:
            line = proc.lines.get(timeout=timeout)
            if wanted(line):
                return line
    except queue.Empty:
        raise AssertionError(f"no such line within {timeout} s; it printed: {''.join(proc.stdout)[-3000:]}") from None


def wall_time_zeroed(bag: dict[str, list[tuple[int, bytes]]]) -> dict[str, list[tuple[int, bytes]]]:
    """The bag's messages with each controller_state's compute_time (the law's wall time) zeroed."""
    import dataclasses

    from bracing_core.typestore import CONTROLLER_STATE, bracing_typestore

    store = bracing_typestore()

    def zeroed(data: bytes) -> bytes:
        msg = dataclasses.replace(store.deserialize_cdr(data, CONTROLLER_STATE), compute_time=0.0)
        return bytes(store.serialize_cdr(msg, CONTROLLER_STATE))

    states = [(stamp, zeroed(data)) for stamp, data in bag["/controller_state"]]
    return {**bag, "/controller_state": states}


def test_two_runs_through_reused_processes_record_the_bag_of_a_fresh_run(tmp_path: Path) -> None:
    first, second = tmp_path / "first", tmp_path / "second"
    plan = plan_run(RunOptions(PAPER_YAML, first, duration=DURATION_S))
    params = plan.node_params
    params[SIMULATOR] |= {"wait_for_reset": True, "min_status_subscribers": 1}  # the recorder: no bracing-pair here
    for out in (first, second):
        out.mkdir()
        write_params(out / PARAMS_FILE, params)
    recorder, controller, simulator = plan.processes(first)
    env = isolated_env()
    rec = Proc([*recorder.argv(), "--stay"], env)
    logs = {name: (tmp_path / f"{name}.log").open("w") for name in ("controller", "simulator")}
    nodes = [
        subprocess.Popen(p.argv(), env=env, stdout=logs[p.name], stderr=subprocess.STDOUT, cwd=REPO_ROOT)
        for p in (controller, simulator)
    ]
    try:
        wait_for(rec, wrote(first / "bag"), 120.0)
        assert nodes[1].poll() is None  # the simulator stays
        asked = {"output": str(second / "bag"), "params_files": [str(second / PARAMS_FILE)]}
        assert set_recorder(env, asked) == (True, "")
        wait_for(rec, lambda line: line == "recorder ready", 30.0)
        reset = subprocess.run([sys.executable, "-c", RESET], env=env, capture_output=True, text=True, timeout=90)
        assert reset.returncode == 0, reset.stderr[-2000:]
        wait_for(rec, wrote(second / "bag"), 120.0)
    finally:
        for proc in (nodes[1], nodes[0], rec.popen):
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        codes = []
        for proc in (nodes[1], nodes[0], rec.popen):
            try:
                codes.append(proc.wait(timeout=30))
            except subprocess.TimeoutExpired:
                proc.kill()
                codes.append(proc.wait())
        for log in logs.values():
            log.close()
    sim_log = (tmp_path / "simulator.log").read_text()
    assert codes == [0, 0, 0], f"{codes}\n{sim_log[-3000:]}"
    assert "reset_simulation: back to the initial state at t = 0.000000 s" in sim_log
    assert "joint_states went back in time" in (tmp_path / "controller.log").read_text()
    one, two = wall_time_zeroed(raw_bag(first / "bag")), wall_time_zeroed(raw_bag(second / "bag"))
    assert len(one["/joint_states"]) == plan.expected_states and len(one["/tf"]) == plan.expected_states
    assert two == one  # every topic, every message: stamps and bytes
