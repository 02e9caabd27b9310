"""Logging never raises: every ordered pair of report kinds (and so of severities) goes through
each node process, over DDS, and each report is logged.

rclpy fixes a call site's severity at its first call; a report helper that logged every
severity from one line killed the node at the first kind of another severity (a watchdog
warning, then a stale-stamp error). Reports are throttled per kind (1 s by default); the
tests set ``log_throttle_period: 0`` so that every report is logged and counted.
"""

from __future__ import annotations

import itertools
import json
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from lockstep_driver import JOINTS
from ros_helpers import drive, node_argv, params_file

# Simulator: the driver's kind -> what the log says of it.
SIM_REPORTS = {
    "nan": "non-finite values for ['joint1']",
    "inf": "non-finite values for ['joint4']",
    "length": "4 names but 3 values",
    "missing-names": "unknown [], missing ['joint4']",
    "unknown-names": "unknown ['joint9']",
    "duplicate": "duplicate joint names",
    "mode-1": "mode torque but the simulator is configured for voltage",
    "mode-7": "mode unknown (7)",
    "from the future": "is from the future",
    "stale": "is stale",
    "cut-short": "motor_command rejected: not a bracing_msgs/msg/MotorCommand: Invalid sequence length 4",
    "malformed": "motor_command rejected: not a bracing_msgs/msg/MotorCommand: Invalid string length",
    "watchdog": "no valid motor_command",
    "saturated": "saturated to +/-",
    "absurd": "would not be finite",
}

GOOD_STATE = {"name": JOINTS, "position": (np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi).tolist(), "velocity": [0.0] * 4}
# Controller: kind -> (the joint_states sent, what the log says of it).
CONTROLLER_REPORTS: dict[str, tuple[dict[str, object], str]] = {
    "malformed": ({"raw_hex": "00010000" + "ff" * 40}, "JointState: Invalid string length"),
    "missing": ({**GOOD_STATE, "name": JOINTS[:3], "position": [0.0] * 3, "velocity": [0.0] * 3}, "missing joints"),
    "duplicate": ({**GOOD_STATE, "name": [*JOINTS[:3], "joint1"]}, "duplicate joint names"),
    "length": ({**GOOD_STATE, "velocity": [0.0] * 3}, "4 names, 4 positions, 3 velocities"),
    "non-finite": ({**GOOD_STATE, "velocity": [0.0, float("nan"), 0.0, 0.0]}, "non-finite position or velocity"),
    "stamp": ({**GOOD_STATE, "stamp": [2**31 - 1, 2**32 - 1]}, "cannot be answered"),
    "command": ({**GOOD_STATE, "velocity": [1e200] * 4}, "the law's output is not finite"),
    "damped": ({**GOOD_STATE, "position": [0.0] * 4}, "B is near-singular"),  # warning; still answered
}


def every_ordered_pair(kinds: list[str]) -> list[str]:
    """A sequence in which every ordered pair (a, b) of ``kinds``, a == b included, appears
    consecutively (an Eulerian circuit of the complete digraph with loops, by Hierholzer)."""
    unused = {a: list(kinds) for a in kinds}
    stack, circuit = [kinds[0]], []
    while stack:
        if unused[stack[-1]]:
            stack.append(unused[stack[-1]].pop())
        else:
            circuit.append(stack.pop())
    return circuit[::-1]


def test_every_ordered_pair_appears() -> None:
    kinds = ["a", "b", "c"]
    sequence = every_ordered_pair(kinds)
    pairs = set(itertools.pairwise(sequence))
    assert pairs == {(a, b) for a in kinds for b in kinds} and len(sequence) == 10


WATCHDOG_TIMEOUTS_S = (0.05, 0.5, 2.0)
"""command_timeout of each try [s]. The watchdog waits this long on every step the driver leaves unanswered
(45 of them in the two runs), so the first try is short; a try in which the machine delayed an answer past
it (``late_answers``) cannot be counted and is run again with the next, larger one."""


def late_answers(log: str, sequence: list[str], stamps: list[float]) -> list[float]:
    """[s] the states whose answer came after the watchdog had acted, as the log shows: a watchdog report
    for a state the driver answered, or an absurd answer never refused (a late answer is stale instead).
    ``stamps``: each state's stamp, in the order the driver answered them with ``sequence``."""
    watched = {float(t) for t in re.findall(r"no valid motor_command for t = ([0-9.]+) s", log)}
    refused = {float(t) for t in re.findall(r"its step at t = ([0-9.]+) s would not be finite", log)}
    kind_at = dict(zip(stamps[: len(sequence)], sequence, strict=True))  # the final state is answered too
    late = {t for t in watched if kind_at.get(t) not in ("watchdog", "absurd")}
    late |= {t for t, kind in kind_at.items() if kind == "absurd" and t not in refused}
    return sorted(late)


@pytest.mark.parametrize("limit", [0.0, 100.0], ids=["no-limit", "limit"])
def test_simulator_logs_every_ordered_pair_of_report_kinds(tmp_path: Path, limit: float) -> None:
    """With a voltage limit, 1e6 V is saturated (a warning); without one, 1e300 V is refused (an error)."""
    kinds = [k for k in SIM_REPORTS if k != ("absurd" if limit else "saturated")]
    # No stale stamp exists at t = 0: start elsewhere.
    sequence = ["nan", *every_ordered_pair(kinds)]
    sequence_file = tmp_path / "kinds.json"
    sequence_file.write_text(json.dumps(sequence))
    for command_timeout in WATCHDOG_TIMEOUTS_S:
        overrides = {
            "duration": len(sequence) * 1e-3,
            "command_timeout": command_timeout,
            "log_throttle_period": 0.0,
            "motors.voltage_limit": limit,
        }
        extra = params_file(tmp_path, "bracing_simulator", overrides)
        driver, node, log = drive(node_argv("bracing_sim.node", extra), ["sim-kinds", str(sequence_file)], True)
        assert node.returncode == 0, log  # alive to its end
        assert driver.returncode == 0, driver.stdout + driver.stderr + log
        assert "finished at t = " in log
        states = json.loads(driver.stdout.strip().splitlines()[-1])["states"]
        assert len(states) == len(sequence) + 1
        stamps = [round(sec + nanosec * 1e-9, 6) for sec, nanosec in (state["stamp"] for state in states)]
        if not (late := late_answers(log, sequence, stamps)):
            break
    assert not late, f"answers to t = {late} s came after a {command_timeout} s watchdog, every try"
    counts = Counter(sequence)
    counts["watchdog"] += counts["absurd"]  # a refused command is as good as none: the watchdog acts
    for kind in kinds:
        assert log.count(SIM_REPORTS[kind]) == counts[kind], (kind, log[-3000:])


def test_controller_logs_every_ordered_pair_of_report_kinds(tmp_path: Path) -> None:
    sequence = every_ordered_pair(list(CONTROLLER_REPORTS))
    inputs = []
    for kind in sequence:
        state, _ = CONTROLLER_REPORTS[kind]
        inputs.append({**state, "no_wait": kind != "damped"})
    inputs.append(GOOD_STATE)  # answered once every report before it was handled
    states_file = tmp_path / "states.json"
    states_file.write_text(json.dumps(inputs))
    extra = params_file(tmp_path, "bracing_controller", {"log_throttle_period": 0.0})
    driver, node, log = drive(node_argv("bracing_controller.node", extra), ["controller", str(states_file)])
    assert node.returncode in (0, -15), log  # stopped by the test, not by a report
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    answers = json.loads(driver.stdout.strip().splitlines()[-1])["answers"]
    assert answers[-1] is not None, log
    counts = Counter(sequence)
    for kind, (_, report) in CONTROLLER_REPORTS.items():
        assert log.count(report) == counts[kind], (kind, log[-3000:])
    assert "Traceback" not in log
