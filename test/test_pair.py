"""bracing-pair: real node processes over DDS, a rosbag2 bag, the report."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import reference_series
from conftest import build_scenario, run_closed_loop
from ros_helpers import isolated_env, pair_argv, run, start
from rosbags.highlevel import AnyReader

from bracing_analysis.animation import DEFAULT_INTERVAL_S
from bracing_analysis.bag import read_series
from bracing_analysis.drawing import report_series
from bracing_analysis.summary import compute_summary, flat_summary

STEP_TOPICS = [
    "joint_states",
    "motor_command",
    "motor_state",
    "contacts",
    "controller_state",
    "contact_wrench/elbow",
    "/clock",
]


def read_bag(bag: Path) -> dict[str, list[tuple[int, object]]]:
    messages: dict[str, list[tuple[int, object]]] = {}
    with AnyReader([bag]) as reader:  # definitions come from the bag itself
        for connection, timestamp, raw in reader.messages():
            messages.setdefault(connection.topic.lstrip("/") if connection.topic != "/clock" else "/clock", []).append(
                (timestamp, reader.deserialize(raw, connection.msgtype))
            )
    return messages


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    output = tmp_path_factory.mktemp("pair") / "run"
    done = run(pair_argv(output, "--duration", "1.0"), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return output


def test_bag_has_every_topic_and_no_missing_step(paper_run: Path) -> None:
    messages = read_bag(paper_run / "bag")
    steps = 1001  # states 0..1000 of a 1 s run at 1 ms
    for topic in STEP_TOPICS:
        assert topic in messages, f"{topic} missing from the bag"
        stamps = sorted(
            msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            if hasattr(msg, "header")
            else msg.clock.sec * 10**9 + msg.clock.nanosec
            for _, msg in messages[topic]
        )
        assert stamps == [k * 1_000_000 for k in range(steps)], f"{topic}: steps missing or repeated"


def test_a_bag_from_batches_is_the_bag_from_every_topic(paper_run: Path, tmp_path: Path) -> None:
    """bracing-pair hands the per-state messages to the recorder in batches (record_batch); with it off
    the recorder subscribes to every topic, as any rosbag2 recorder. The two bags hold the same
    messages, byte for byte at the same bag times (controller_state but its compute_time, a wall-clock
    measurement), and the derived /tf and markers alike."""
    output = tmp_path / "run"
    done = run(pair_argv(output, "--duration", "1.0", "--no-animation", "--set", "record_batch=0"), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    for run_dir, batch in ((paper_run, 100), (output, 0)):  # the two paths were taken
        assert f"record_batch: {batch}" in (run_dir / "params.yaml").read_text()
    bags = []
    for bag in (paper_run / "bag", output / "bag"):
        with AnyReader([bag]) as reader:
            topics: dict[str, list[tuple[int, bytes]]] = {}
            for connection, timestamp, raw in reader.messages():
                data = bytes(raw)
                if connection.topic == "/controller_state":  # compute_time: the float64 at the end
                    data = data[:-8]
                topics.setdefault(connection.topic, []).append((timestamp, data))
        bags.append(topics)
    batched, every = bags
    assert set(batched) == set(every)
    for topic in every:
        assert len(batched[topic]) == len(every[topic]) >= 1, topic
        assert batched[topic] == every[topic], topic


def test_pair_trajectory_equals_in_process_loop(paper_run: Path) -> None:
    messages = read_bag(paper_run / "bag")
    states = sorted(messages["joint_states"], key=lambda m: (m[1].header.stamp.sec, m[1].header.stamp.nanosec))
    reference = run_closed_loop(build_scenario(), 1.0)
    positions = np.array([m.position for _, m in states])
    np.testing.assert_array_equal(positions[:-1], reference.position)  # bit for bit: one engine, one clock
    np.testing.assert_array_equal(positions[-1], reference.final_position)
    forces = np.array(
        [
            m.contacts[0].normal_force
            for _, m in sorted(messages["contacts"], key=lambda m: (m[1].header.stamp.sec, m[1].header.stamp.nanosec))
        ]
    )
    np.testing.assert_array_equal(forces[:-1], reference.normal_force[:, 0])


def test_summary_agrees_with_the_bag(paper_run: Path) -> None:
    summary = json.loads((paper_run / "summary.json").read_text())
    recomputed = compute_summary(read_series(paper_run / "bag"), wall_time_s=summary["wall_time_s"])
    assert summary.keys() == recomputed.keys()
    summary, recomputed = flat_summary(summary), flat_summary(recomputed)  # contacts.<name>.<key> as keys
    for key, value in recomputed.items():
        if value is None or isinstance(value, (str, bool)):  # None: e.g. hand errors over t >= 2 s of a 1 s run
            assert summary[key] == value, key
        else:
            assert summary[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key
    assert summary["sim_time_s"] == pytest.approx(1.0)
    assert summary["constraint_residual_max_m"] < 1e-9
    for png in ("hand_y.png", "hand_z.png", "brace_y.png", "normal_force.png", "energy.png", "motor_temperature.png"):
        assert (paper_run / png).stat().st_size > 10_000


def test_timeline_accounts_for_the_whole_run(paper_run: Path) -> None:
    timeline = json.loads((paper_run / "timeline.json").read_text())
    phases = [timeline[key] for key in ("startup_s", "stepping_s", "shutdown_s", "report_s")]
    assert all(value > 0 for value in phases), timeline
    assert sum(phases) == pytest.approx(timeline["whole_run_s"], abs=1e-9)
    at = {event["what"]: event["t_s"] for event in timeline["events"]}
    # Every moment the timeline names, in the order a run goes through them.
    order = [
        "processes started",
        "first step",
        "last step",
        "bag closed",
        "bag read",
        "bag checked",
        "summary.json",
        "last file written",
    ]
    assert [at[what] for what in order] == sorted(at[what] for what in order), at
    # Bounds by cause, not by wall time (a busy machine may delay any process): the simulator steps once it
    # has matched the controller's state subscription, made after the controller is configured; the controller
    # says it answers before it takes a state (and the run ends on its answers); the recorder says it is
    # ready once subscribed (the simulator waits for that match, not for the word) and before it closes the bag.
    for what in ("simulator configured", "controller configured"):
        assert 0 < at[what] <= at["first step"], what
    assert 0 < at["controller answering"] < at["last step"]
    assert 0 < at["recorder ready"] < at["recorder closed the bag"]
    drawn = {what for what in at if what.startswith("plot ") or what == "animation"}
    pngs = ("hand_y.png", "hand_z.png", "brace_y.png", "normal_force.png", "energy.png", "motor_temperature.png")
    assert drawn == {f"plot {png}" for png in pngs} | {"animation"}
    assert all(at["summary.json"] <= at[what] <= at["last file written"] for what in drawn)
    assert timeline["stepping_s"] == pytest.approx(at["last step"] - at["first step"], abs=1e-3)


def test_report_is_the_general_paths_report(paper_run: Path, tmp_path: Path) -> None:
    """The pair reads its bag once, column-wise, and draws in processes of its own; on the same
    bag, the way reports were made before (every message decoded by rosbags, drawn in this
    process) gives the same summary.json and the same files, byte for byte."""
    summary = json.loads((paper_run / "summary.json").read_text())
    reference = report_series(
        reference_series.read_series(paper_run / "bag"),
        tmp_path,
        wall_time_s=summary["wall_time_s"],
        animation_interval_s=DEFAULT_INTERVAL_S,
        parallel=False,
    )
    assert reference == summary
    assert (tmp_path / "summary.json").read_bytes() == (paper_run / "summary.json").read_bytes()
    for name in ("hand_y.png", "hand_z.png", "brace_y.png", "normal_force.png", "energy.png", "animation.gif"):
        assert (tmp_path / name).read_bytes() == (paper_run / name).read_bytes(), name


def _wait_for_progress(output: Path, timeout: float = 60.0) -> None:
    log = output / "logs" / "simulator.log"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if log.exists() and "progress t=0." in log.read_text(errors="replace"):
            return
        time.sleep(0.1)
    raise AssertionError("the simulator never made progress")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_mid_run_leaves_a_readable_bag(tmp_path: Path, sig: signal.Signals) -> None:
    output = tmp_path / "run"
    proc = start(pair_argv(output, "--duration", "30"), isolated_env())
    try:
        _wait_for_progress(output)
        time.sleep(0.5)
        proc.send_signal(sig)
        out = proc.communicate(timeout=60)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, out
    assert f"interrupted ({sig.name})" in out
    messages = read_bag(output / "bag")
    assert len(messages["joint_states"]) > 10
    assert subprocess.run(["pgrep", "-f", str(output)], capture_output=True).stdout == b""  # nothing left running


def test_killed_pair_stops_its_processes_and_leaves_a_readable_bag(tmp_path: Path) -> None:
    """SIGKILL gives bracing-pair no chance to stop its processes: they stop by themselves (the
    kernel tells them) instead of living on in a domain id the next run may be given."""
    output = tmp_path / "run"
    proc = start(pair_argv(output, "--duration", "30"), isolated_env())
    try:
        _wait_for_progress(output)
        time.sleep(0.5)
        proc.kill()
        proc.wait(10)
        deadline = time.monotonic() + 30.0
        while subprocess.run(["pgrep", "-f", str(output)], capture_output=True).stdout:
            assert time.monotonic() < deadline, "a process of the killed run is still running"
            time.sleep(0.2)
    finally:
        subprocess.run(["pkill", "-KILL", "-f", str(output)], capture_output=True)
    messages = read_bag(output / "bag")  # the recorder closed it
    assert len(messages["joint_states"]) > 10


def test_killed_controller_fails_the_run_with_a_clear_message(tmp_path: Path) -> None:
    output = tmp_path / "run"
    proc = start(pair_argv(output, "--duration", "30"), isolated_env())
    try:
        _wait_for_progress(output)
        subprocess.run(["pkill", "-KILL", "-f", f"bracing_controller.node.*{output}"], check=True)
        out = proc.communicate(timeout=60)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, out
    assert "controller exited" in out
    assert "controller|" in out  # the tail of its log is shown
    read_bag(output / "bag")  # still readable


@pytest.mark.parametrize(
    "extra", [["--no-bracing"], ["--free-space"], ["--mode", "torque"]], ids=["no-bracing", "free-space", "torque"]
)
def test_pair_variants_run_and_record(tmp_path: Path, extra: list[str]) -> None:
    output = tmp_path / "run"
    done = run(pair_argv(output, "--duration", "0.3", *extra), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    messages = read_bag(output / "bag")
    assert len(messages["joint_states"]) == 301 and len(messages["motor_command"]) == 301
    summary = json.loads((output / "summary.json").read_text())
    if "--no-bracing" in extra:  # the floor stays, an obstacle the elbow rests on: it pushes, never pulls
        assert all(len(m.contact_name) == 0 for _, m in messages["controller_state"])  # no brace task
        forces = [m.contacts[0].normal_force for _, m in messages["contacts"]]
        assert min(forces) >= 0.0 and max(forces) > 1.0
        assert summary["bracing"] is False and summary["contacts"]["elbow"]["braced"] is False
        assert summary["max_penetration_m"] < 1e-9
    elif "--free-space" in extra:  # the floor removed: only watched, and the elbow goes through it
        assert all(not m.contacts[0].active and m.contacts[0].normal_force == 0.0 for _, m in messages["contacts"])
        assert summary["bracing"] is False and summary["max_penetration_m"] > 0.01
    else:  # torque input: the force equals its set-point at every step (eq. 40)
        assert all(m.mode == 1 for _, m in messages["motor_command"])
        forces = [m.contacts[0].normal_force for _, m in messages["contacts"]]
        assert max(abs(f - 10.0) for f in forces) < 1e-9
