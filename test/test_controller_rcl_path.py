"""The controller's per-state path on rcl (bracing_rcl, C++) against its Python path: the same bag, message for
message and byte for byte (controller_state but its compute_time, a wall-clock measurement), the same check
with the same refusals, and the byte templates it writes laid out as ``bracing_ros.wire``'s.

The hostile-input tests of the controller (test_fuzz, test_hostile_input) run on both paths
(``CONTROLLER_PATHS``)."""

from __future__ import annotations

import math
import re
import signal
import struct
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pytest
from ros_helpers import PATH_LINES, isolated_env, pair_argv, run
from rosbags.highlevel import AnyReader

import bracing_engine as engine
from bracing_controller.rcl_path import PATH_ENV
from bracing_core.answering import StateError, joint_vectors
from bracing_ros import stop_signal, wire

RUN_S = 0.3
"""[s] of sim time a compared run lasts (300 states)."""
NOT_COMPARED = {"/rosout", "/parameter_events"}
"""Topics whose messages carry wall-clock stamps or the path's own log line."""


def recorded(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of the bag by topic: (bag time, CDR bytes), controller_state's without its compute_time."""
    topics: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([bag]) as reader:
        for connection, timestamp, raw in reader.messages():
            data = bytes(raw)
            if connection.topic == "/controller_state":  # compute_time: the float64 at the end
                data = data[:-8]
            topics.setdefault(connection.topic, []).append((timestamp, data))
    return topics


def pair_runs(
    tmp_path_factory: pytest.TempPathFactory, env_name: str, paths: Iterable[str], *extra: str
) -> dict[str, Path]:
    """A pair run of the paper's arm (RUN_S) with ``env_name`` set to each of ``paths``: its output directory.
    ``extra``: bracing-pair's further arguments."""
    out = {}
    for path in paths:
        output = tmp_path_factory.mktemp(f"pair-{path}") / "run"
        env = isolated_env(**{env_name: path})
        done = run(pair_argv(output, "--duration", str(RUN_S), "--no-animation", *extra), env=env, timeout=300)
        assert done.returncode == 0, done.stdout + done.stderr
        out[path] = output
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A pair run of the paper's arm on each path."""
    return pair_runs(tmp_path_factory, PATH_ENV, PATH_LINES)


def test_each_run_took_its_path(runs: dict[str, Path]) -> None:
    """The Python path said so; the C++ path answered the states itself (the simulator's states have its
    template's layout) and handed none over. A state may come while the node's executor serves its services
    between states (the loop idle at the start or the end): the executor's callback answers it on the Python
    path, as before."""
    for path, output in runs.items():
        log = (output / "logs" / "controller.log").read_text()
        assert PATH_LINES[path] in log, log[-3000:]
    log = (runs["rcl"] / "logs" / "controller.log").read_text()
    found = re.search(r"per-state path: (\d+) states answered in C\+\+ on rcl, (\d+) by the Python path", log)
    assert found is not None, log[-3000:]
    states = round(RUN_S * 1000) + 1
    assert states - 3 <= int(found[1]) <= states and int(found[2]) == 0, found[0]
    # the C++ path waits for the states itself: it says how soon each was taken once DDS had it
    landed = re.search(r"taken after landing \[us\]: p50 ([0-9.]+), p99 ([0-9.]+), max ([0-9.]+)", log)
    assert landed is not None and 0.0 < float(landed[1]) <= float(landed[2]) <= float(landed[3]), log[-3000:]


def same_bags(runs: dict[str, Path]) -> dict[str, list[tuple[int, bytes]]]:
    """The rcl run's bag, found equal to the Python run's on every compared topic, message for message."""
    rcl, python = (recorded(runs[path] / "bag") for path in ("rcl", "python"))
    assert set(rcl) == set(python)
    for topic in sorted(set(python) - NOT_COMPARED):
        assert len(rcl[topic]) == len(python[topic]) >= 1, topic
        assert rcl[topic] == python[topic], topic
    return rcl


def test_the_rcl_path_bag_equals_the_python_path_bag(runs: dict[str, Path]) -> None:
    commands = same_bags(runs)["/motor_command"]
    assert len(commands) == round(RUN_S * 1000) + 1, len(commands)  # every state answered


def test_the_compute_time_is_the_law_s_on_both_paths(runs: dict[str, Path]) -> None:
    """compute_time, the one field that differs: the law's wall time measured on both paths (positive and finite,
    not left zero; how long, not asserted)."""
    for path, output in runs.items():
        with AnyReader([output / "bag"]) as reader:
            connections = [c for c in reader.connections if c.topic == "/controller_state"]
            times = [
                struct.unpack_from("<d", bytes(raw), len(raw) - 8)[0] for _, _, raw in reader.messages(connections)
            ]
        assert times and all(0.0 < t < math.inf for t in times), (path, min(times), max(times))


@pytest.mark.parametrize(
    ("position", "stamp_ns", "kind", "message"),
    [
        ([0.0, math.nan, 0.0, 0.0], 0, "non-finite", "non-finite position or velocity"),
        ([0.0, 0.0, math.inf, 0.0], 0, "non-finite", "non-finite position or velocity"),
        (
            [0.0] * 4,
            2**31 * 10**9,
            "stamp",
            f"stamp {2**31 * 10**9} ns cannot be answered (builtin_interfaces/Time: int32 seconds)",
        ),
        ([0.0] * 4, -(2**31) * 10**9 - 1, "stamp", None),
    ],
)
def test_one_state_check_for_both_paths(position: list[float], stamp_ns: int, kind: str, message: str | None) -> None:
    """The engine's ``state_refusal`` is the check: the Python path raises what it says, and the C++ path calls
    it (through ``law_api``) before the law."""
    q, dq = np.array(position), np.zeros(4)
    refused = engine.state_refusal(stamp_ns, q, dq)
    assert refused is not None and refused[0] == kind
    if message is not None:
        assert refused[1] == message
    names = ["joint1", "joint2", "joint3", "joint4"]
    with pytest.raises(StateError) as raised:
        joint_vectors(names, q, dq, stamp_ns, names)
    assert (raised.value.kind, str(raised.value)) == refused
    assert engine.state_refusal(2**31 * 10**9 - 1, np.zeros(4), np.zeros(4)) is None  # the last stamp answered


def test_a_template_s_layout_places_every_value_as_fill_does() -> None:
    """What the C++ path writes at each offset is what ``Template.fill`` packs there, and the constant runs are
    the rest of the message."""
    encoder = wire.ControllerStateEncoder(["elbow", "wrist"], 4)
    data, constants, offsets, codes = encoder.template.layout()
    assert codes == "iI" + "d" * (3 + 3 + 2 + 6 + 6 + 4 + 1)
    values = np.arange(len(codes) - 2) + 0.5
    filled = encoder.template.fill((7, 123), values.tolist()[:3], values.tolist()[3:6], values.tolist()[6:8],
                                   values.tolist()[8:14], values.tolist()[14:20], values.tolist()[20:24],
                                   values.tolist()[24:])  # fmt: skip
    manual = bytearray(data)
    struct.pack_into("<iI", manual, offsets[0], 7, 123)
    assert offsets[1] == offsets[0] + 4
    for offset, value in zip(offsets[2:], values, strict=True):
        struct.pack_into("<d", manual, offset, value)
    assert bytes(manual) == filled
    covered = sorted([(o, n) for o, n in constants] + [(o, 4) for o in offsets[:2]] + [(o, 8) for o in offsets[2:]])
    end = 0
    for offset, length in covered:  # the constants and the values tile the message (padding inside slots aside)
        assert offset >= end
        assert all(b == 0 for b in data[end:offset])  # only alignment padding between them
        end = offset + length
    assert end == len(data)


def test_a_stop_signal_inside_held_comes_at_its_end(monkeypatch: pytest.MonkeyPatch) -> None:
    """The C++ path's answer and its copy for the recorder are not cut apart by a stop signal: inside
    ``stop_signal.held`` the signal's KeyboardInterrupt waits for the block's end; outside, it comes at once."""
    monkeypatch.setattr(stop_signal, "_requested", False)
    done = []
    with pytest.raises(KeyboardInterrupt), stop_signal.held:
        stop_signal.request_stop(signal.SIGINT, None)
        done.append("kept")
    assert done == ["kept"]
    with pytest.raises(KeyboardInterrupt):
        stop_signal.request_stop(signal.SIGINT, None)
    with stop_signal.held:  # nothing pending: a quiet end
        done.append("again")
    assert done == ["kept", "again"]
