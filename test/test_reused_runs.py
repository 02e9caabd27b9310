"""Runs through reused processes: one simulator (``wait_for_reset``), one controller and one recorder
(``--stay``) make two runs of the pair's plan, the second begun by reset_simulation once the recorder has
opened its bag; the second bag equals the first, a fresh run's, message for message (the controller's
compute_time, a wall time, aside)."""

from __future__ import annotations

import queue
from collections.abc import Callable
from pathlib import Path

from test_recorder_bag_switch import raw_bag
from test_recorder_report import Proc

from bracing_core.variants import BRACED

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
    from test_reused_variants import record_runs  # the runs in turn through one simulator, controller and recorder

    first, second = record_runs(tmp_path, (BRACED, BRACED))  # the second begun by a reset alone
    sim_log = (tmp_path / "simulator.log").read_text()
    assert "reset_simulation: back to the initial state at t = 0.000000 s" in sim_log
    assert "joint_states went back in time" in (tmp_path / "controller.log").read_text()
    one, two = wall_time_zeroed(raw_bag(first)), wall_time_zeroed(raw_bag(second))
    assert two == one  # every topic, every message: stamps and bytes
