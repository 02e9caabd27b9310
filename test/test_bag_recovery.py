"""Recordings that survive their recorder: a bag cut short (its recorder killed: no summary, no
metadata.yaml) is recovered as ``ros2 bag reindex`` does, by bracing-pair and by bracing-report.

Before: kill -9 on the recorder mid-run left bag.mcap without its end; rosbags and bracing-report could
not read it (exit 2) and bracing-pair did not say the recording was lost.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest
from ros_helpers import isolated_env, pair_argv, run, start
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapReader
from rosbags.typesys import Stores, get_typestore

from bracing_analysis.bag_events import custom_data
from bracing_analysis.bag_recovery import cut_files, recover_bag
from bracing_recorder.recorder import LATCHED  # the QoS offer of a latched topic, as the recorder writes it

STORE = get_typestore(Stores.ROS2_JAZZY)
String = STORE.types["std_msgs/msg/String"]
Float64MultiArray = STORE.types["std_msgs/msg/Float64MultiArray"]
Layout = STORE.types["std_msgs/msg/MultiArrayLayout"]

Message = tuple[str, str, int, bytes]  # topic, type, timestamp [ns], CDR


def _write_bag(path: Path, count: int, payload: int) -> list[Message]:
    """A bag of two topics (one latched) and ``count`` messages of ``payload`` doubles each, as the recorder
    writes it (rosbags, mcap, version 8); the messages written, in order."""
    written: list[Message] = []
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.set_custom_data("scenario", "cut")
        note = writer.add_connection("/note", String.__msgtype__, typestore=STORE, offered_qos_profiles=[LATCHED])
        data = writer.add_connection("/data", Float64MultiArray.__msgtype__, typestore=STORE)
        raw = bytes(STORE.serialize_cdr(String(data="the arm"), String.__msgtype__))
        writer.write(note, 0, raw)
        written.append(("/note", String.__msgtype__, 0, raw))
        for k in range(count):
            msg = Float64MultiArray(layout=Layout(dim=[], data_offset=0), data=np.full(payload, float(k)))
            raw = bytes(STORE.serialize_cdr(msg, Float64MultiArray.__msgtype__))
            writer.write(data, 1_000_000 * (k + 1), raw)
            written.append(("/data", Float64MultiArray.__msgtype__, 1_000_000 * (k + 1), raw))
    return written


def _read(bag: Path) -> tuple[list[Message], dict[str, list[Qos]]]:
    with AnyReader([bag]) as reader:
        messages = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages()]
        offers = {c.topic: list(c.ext.offered_qos_profiles) for c in reader.connections}  # type: ignore[union-attr]
    return sorted(messages, key=lambda m: m[2]), offers


def _whole_before(mcap: Path, cut_at: int) -> int:
    """How many messages a cut at byte ``cut_at`` leaves whole: those of the chunks written entirely before
    it (rosbags' own index of the whole file says where each chunk is and what it holds)."""
    return sum(
        sum(chunk.channel_count.values())
        for chunk in _chunks(mcap)
        if chunk.chunk_start_offset + chunk.chunk_length <= cut_at
    )


def _cut_copy(bag: Path, into: Path, cut_at: int) -> Path:
    """A copy of ``bag`` as a killed recorder leaves it: its mcap cut at byte ``cut_at``, no metadata.yaml."""
    copy = into / "bag"
    copy.mkdir(parents=True)
    with (bag / "bag.mcap").open("rb") as source, (copy / "bag.mcap").open("wb") as target:
        target.write(source.read(cut_at))
    return copy


def test_a_bag_cut_at_any_byte_keeps_every_message_whose_record_was_complete(tmp_path: Path) -> None:
    whole = tmp_path / "whole" / "bag"
    written = _write_bag(whole, count=1500, payload=250)  # ~3 MB: 3 chunks of 1 MiB
    size = (whole / "bag.mcap").stat().st_size
    ends = [c.chunk_start_offset + c.chunk_length for c in _chunks(whole / "bag.mcap")]
    assert len(ends) == 3
    offsets = [0, 5, 8, 30, ends[0] - 1, ends[0], ends[0] + 7, (ends[0] + ends[1]) // 2, ends[1], ends[2], size - 1]
    for k, cut_at in enumerate(offsets):
        bag = _cut_copy(whole, tmp_path / f"cut{k}", cut_at)
        with pytest.raises(Exception):  # noqa: B017 (rosbags raises several kinds): unreadable as it is
            _read(bag)
        recovered = recover_bag(bag)
        kept = _whole_before(whole / "bag.mcap", cut_at)
        assert recovered.messages == kept, cut_at
        assert cut_files(bag) == [] and sorted(p.name for p in bag.iterdir()) == ["bag.mcap", "metadata.yaml"]
        messages, offers = _read(bag)
        assert messages == written[:kept]  # a prefix: topic, type, timestamp and bytes, nothing else
        if kept:
            assert offers["/note"] == [LATCHED] and offers["/data"] == []
            assert recovered.last_ns == written[kept - 1][2]
        meta = (bag / "metadata.yaml").read_text()
        assert f"message_count: {kept}" in meta


def test_a_small_bag_cut_anywhere_is_recovered_or_empty(tmp_path: Path) -> None:
    """A bag of one chunk cut at 50 bytes spread over it and at each byte around its chunk's end (the cut
    in any field of any record): never an error; the messages are all there only once the chunk is."""
    whole = tmp_path / "whole" / "bag"
    written = _write_bag(whole, count=3, payload=2)
    (chunk_end,) = [c.chunk_start_offset + c.chunk_length for c in _chunks(whole / "bag.mcap")]
    size = (whole / "bag.mcap").stat().st_size
    for cut_at in sorted({*range(0, size, max(1, size // 50)), *range(chunk_end - 2, chunk_end + 3), size}):
        bag = _cut_copy(whole, tmp_path / f"cut{cut_at}", cut_at)
        recovered = recover_bag(bag)
        assert recovered.messages == (len(written) if cut_at >= chunk_end else 0), cut_at
        assert _read(bag)[0] == (written if cut_at >= chunk_end else [])
        shutil.rmtree(bag.parent)


def _chunks(mcap: Path) -> list:
    reader = McapReader(mcap)
    reader.open()
    try:
        return list(reader.chunks)
    finally:
        reader.close()


def test_recovery_keeps_the_custom_data_of_an_existing_metadata_file_and_adds_the_callers(tmp_path: Path) -> None:
    whole = tmp_path / "whole" / "bag"
    _write_bag(whole, count=10, payload=2)
    bag = tmp_path / "run" / "bag"
    shutil.copytree(whole, bag)
    size = (bag / "bag.mcap").stat().st_size
    os.truncate(bag / "bag.mcap", size - 100)  # the end lost, metadata.yaml still there
    assert cut_files(bag) == [bag / "bag.mcap"]
    recover_bag(bag, {"input_mode": "torque"})
    meta = (bag / "metadata.yaml").read_text()
    assert "scenario: cut" in meta and "input_mode: torque" in meta
    assert len(_read(bag)[0]) == 11


PER_STATE = ["/joint_states", "/motor_command", "/motor_state", "/contacts", "/controller_state", "/clock"]
DT_NS = 1_000_000  # the paper scenario's step


def _stamps(bag: Path) -> dict[str, list[int]]:
    """Each topic's bag timestamps [ns], sorted (the recorder stamps a message with its header stamp)."""
    out: dict[str, list[int]] = {}
    with AnyReader([bag]) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, [])
        for conn, stamp, _ in reader.messages():
            out[conn.topic].append(stamp)
    return {topic: sorted(stamps) for topic, stamps in out.items()}


def _joint_positions(bag: Path) -> dict[int, list[float]]:
    with AnyReader([bag]) as reader:
        wanted = [c for c in reader.connections if c.topic == "/joint_states"]
        return {
            stamp: cast(Any, reader.deserialize(raw, conn.msgtype)).position.tolist()
            for conn, stamp, raw in reader.messages(connections=wanted)
        }


@pytest.fixture(scope="module")
def full_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    output = tmp_path_factory.mktemp("recovery") / "full"
    done = run(pair_argv(output, "--duration", "2", "--no-animation"), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return output


def _kill_once_a_chunk_is_written(output: Path, proc: subprocess.Popen[str], module: str) -> None:
    """SIGKILL to one process of the run only, once the first chunk of its bag is on disk (rosbags writes a
    chunk per MiB of messages: before that, a killed recorder leaves nothing to recover). Its pid is the
    one process whose command line runs ``module`` with this run's files."""
    mcap = output / "bag" / "bag.mcap"
    deadline = time.monotonic() + 120.0  # generous: the run's start on a loaded 2-core machine
    while not (mcap.exists() and mcap.stat().st_size > 2**20 + 4096):
        assert proc.poll() is None and time.monotonic() < deadline, "the run ended before a chunk was written"
        time.sleep(0.02)
    found = subprocess.run(["pgrep", "-f", f"{module} .*{output}"], capture_output=True, text=True)
    (pid,) = [int(p) for p in found.stdout.split()]
    os.kill(pid, signal.SIGKILL)


def _pair_run_killing(output: Path, module: str) -> tuple[int, str]:
    """A 2 s bracing-pair run whose process ``module`` is killed (SIGKILL) once a chunk is written: (exit code,
    its output)."""
    proc = start(pair_argv(output, "--duration", "2", "--no-animation"), isolated_env())
    try:
        _kill_once_a_chunk_is_written(output, proc, module)
        out = proc.communicate(timeout=180)[0]
        return proc.returncode, out
    finally:
        if proc.poll() is None:
            proc.kill()


def test_pair_recovers_the_bag_of_a_killed_recorder(tmp_path: Path, full_run: Path) -> None:
    """Before: exit 1 "the recorder exited with code -9", bag.mcap without its end, nothing could read it."""
    output = tmp_path / "killed"
    code, out = _pair_run_killing(output, "bracing_recorder.command")
    assert code == 1, out
    said = re.search(
        r"the recorder died \(signal 9, SIGKILL\) at t >= ([\d.]+) s; the bag was recovered up to "
        r"t = ([\d.]+) s: (\d+) messages",
        out,
    )
    assert said is not None, out
    summary = json.loads((output / "summary.json").read_text())
    assert any(w.startswith("the recorder died (signal 9, SIGKILL)") for w in summary["warnings"])
    assert subprocess.run(["pgrep", "-f", str(output)], capture_output=True).stdout == b""  # nothing left running

    cut, full = _stamps(output / "bag"), _stamps(full_run / "bag")
    assert sum(len(s) for s in cut.values()) == int(said.group(3))
    assert set(cut) <= set(full) and set(PER_STATE) <= set(cut)
    for topic in PER_STATE:  # each stream a prefix of the whole run's: states 0, 1, ... with no gap
        stamps = cut[topic]
        assert 0 < len(stamps) < len(full[topic]) and stamps == full[topic][: len(stamps)], topic
        assert stamps == [k * DT_NS for k in range(len(stamps))], topic
    assert max(max(s) for s in cut.values() if s) == round(float(said.group(2)) * 1e9)
    assert custom_data(output / "bag") == custom_data(full_run / "bag")  # the recorder's notes, given again
    positions, whole = _joint_positions(output / "bag"), _joint_positions(full_run / "bag")
    assert all(positions[stamp] == whole[stamp] for stamp in positions)  # lockstep: the same run, bit for bit

    again = run([*REPORT, str(output / "bag"), "--output", str(tmp_path / "report"), "--no-animation"], timeout=180)
    assert again.returncode == 0, again.stdout + again.stderr
    assert json.loads((tmp_path / "report" / "summary.json").read_text())["sim_time_s"] == summary["sim_time_s"]


REPORT = [sys.executable, "-m", "bracing_analysis.report"]


def test_a_killed_simulator_still_leaves_a_bag_closed_by_its_recorder(tmp_path: Path) -> None:
    """As before: exit 1 naming the simulator; the recorder, stopped, closes the bag itself (nothing to recover)."""
    output = tmp_path / "killed"
    code, out = _pair_run_killing(output, "bracing_sim.node")
    assert code == 1, out
    assert "the simulator exited with code -9" in out and "simulator|" in out and "recovered" not in out
    assert cut_files(output / "bag") == [] and len(_stamps(output / "bag")["/joint_states"]) > 100


def test_report_recovers_a_bag_cut_short_and_says_so(tmp_path: Path, full_run: Path) -> None:
    """Before: "bracing-report: error: cannot read bag", exit 2."""
    bag = tmp_path / "run" / "bag"
    shutil.copytree(full_run / "bag", bag)
    (bag / "metadata.yaml").unlink()
    size = (bag / "bag.mcap").stat().st_size
    os.truncate(bag / "bag.mcap", size // 2)
    done = run([*REPORT, str(bag), "--no-animation"], timeout=180)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "warning: the bag was cut short (its recorder stopped before closing it) and recovered: " in done.stdout
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["warnings"][0].startswith("the bag was cut short")
    assert 0.0 < summary["sim_time_s"] < 2.0
    assert cut_files(bag) == []
    again = run([*REPORT, "--reindex", str(bag)], timeout=60)
    assert again.returncode == 0 and "whole (it has its metadata.yaml and its end): left as it is" in again.stdout


MUJOCO_KEYS = ("input_mode", "max_penetration_m", "contacts", "normal_force_rms_error_n", "brace_rms_error_m")


def test_report_on_a_mujoco_bag_has_the_contact_metrics_and_input_mode_of_the_pairs_summary(tmp_path: Path) -> None:
    """Before: the report's summary had input_mode null and every contact metric n/a (the MuJoCo robot
    publishes no `contacts` and the controller no motor_command: bracing-pair filled them in itself)."""
    output = tmp_path / "mujoco"
    argv = pair_argv(output, "--duration", "0.3", "--mode", "torque", "--no-animation", "--engine", "mujoco")
    done = run(argv, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    pair = json.loads((output / "summary.json").read_text())
    assert pair["input_mode"] == "torque" and pair["contacts"]["elbow"]["active_fraction"] == 1.0
    again = run([*REPORT, str(output / "bag"), "--output", str(tmp_path / "report"), "--no-animation"], timeout=180)
    assert again.returncode == 0, again.stdout + again.stderr
    report_summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    for key in MUJOCO_KEYS:
        assert report_summary[key] == pair[key], key
