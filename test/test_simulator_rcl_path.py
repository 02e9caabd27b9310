"""The simulator's motor_command path on rcl (bracing_sim.rcl_path, C++) against its Python path: the same bag,
message for message and byte for byte (controller_state but its compute_time, a wall-clock measurement), with
every command the controller sends read in C++.

The simulator's hostile-input tests (test_fuzz, test_hostile_input, test_robustness) run on both paths
(``SIMULATOR_PATHS``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from ros_helpers import SIMULATOR_PATH_LINES, isolated_env, pair_argv, run
from test_controller_rcl_path import NOT_COMPARED, RUN_S, recorded

from bracing_sim.rcl_path import PATH_ENV


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A pair run of the paper's arm with the simulator on each path."""
    out = {}
    for path in SIMULATOR_PATH_LINES:
        output = tmp_path_factory.mktemp(f"sim-{path}") / "run"
        env = isolated_env(**{PATH_ENV: path})
        done = run(pair_argv(output, "--duration", str(RUN_S), "--no-animation"), env=env, timeout=300)
        assert done.returncode == 0, done.stdout + done.stderr
        out[path] = output
    return out


def test_each_run_took_its_path(runs: dict[str, Path]) -> None:
    """The Python path said so; the C++ path read the commands itself (the controller's have the template's
    layout) and handed none over. A command may come while the node's executor serves its services (every
    100 steps): the executor's callback takes it on the Python path, as before."""
    for path, output in runs.items():
        log = (output / "logs" / "simulator.log").read_text()
        assert SIMULATOR_PATH_LINES[path] in log, log[-3000:]
    log = (runs["rcl"] / "logs" / "simulator.log").read_text()
    found = re.search(r"motor_command path: (\d+) read in C\+\+ on rcl, (\d+) by the Python path", log)
    assert found is not None, log[-3000:]
    commands = round(RUN_S * 1000) + 1  # one per state, the final one's too
    assert commands - 4 <= int(found[1]) <= commands and int(found[2]) == 0, found[0]


def test_the_rcl_path_bag_equals_the_python_path_bag(runs: dict[str, Path]) -> None:
    rcl, python = (recorded(runs[path] / "bag") for path in ("rcl", "python"))
    assert set(rcl) == set(python)
    for topic in sorted(set(python) - NOT_COMPARED):
        assert len(rcl[topic]) == len(python[topic]) >= 1, topic
        assert rcl[topic] == python[topic], topic
    assert len(rcl["/joint_states"]) == round(RUN_S * 1000) + 1
