"""The recorder's bulk bag writer: byte for byte the bag rosbags writes message by message.

``BagWriter.write_batch`` builds a batch's MCAP records with numpy and extends the pinned rosbags'
McapWriter; these tests hold it to rosbags' own output (records, chunk boundaries, message indices,
statistics, metadata), so a rosbags upgrade that changes the layout fails here, not in a user's bag.
The recorder's batch path (optional topics entering the bag mid-batch, /clock, the scene's inputs)
is held to its message-by-message path the same way.
"""

from __future__ import annotations

import struct
from array import array
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import cast

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter

from bracing_core.record_batch import BatchPacker, unpack
from bracing_core.stamps import cdr_stamp_ns
from bracing_core.typestore import CLOCK, STRING, VECTOR3_STAMPED, bracing_typestore
from bracing_recorder.bag_batch import BagWriter, header_stamps_ns, message_starts
from bracing_recorder.recorder import BAG_VERSION


def stamped(sec: int, nanosec: int, payload: bytes, little: bool = True) -> bytes:
    """CDR bytes of a message whose first field is a builtin_interfaces/Time (the encapsulation header's
    flag giving the byte order), then ``payload``."""
    order = "<" if little else ">"
    return bytes([0, 1 if little else 0, 0, 0]) + struct.pack(order + "iI", sec, nanosec) + payload


def test_header_stamps_read_as_cdr_stamp_ns_in_either_byte_order() -> None:
    messages = [
        stamped(3, 999_999_999, b"x"),
        stamped(-2, 5, b""),
        stamped(7, 1, b"abc", little=False),
        stamped(2**31 - 1, 4_000_000_000, b"", little=False),
    ]
    data = np.frombuffer(b"".join(messages), np.uint8)
    end = np.cumsum([len(m) for m in messages])
    assert header_stamps_ns(data, message_starts(end)).tolist() == [cdr_stamp_ns(m) for m in messages]


def _stream(n: int, seed: int) -> list[tuple[int, int, bytes]]:
    """(connection index, stamp [ns], bytes) of n messages of mixed sizes, some large (several chunks)."""
    rng = np.random.default_rng(seed)
    sizes = rng.choice([12, 40, 300, 5_000, 200_000], size=n, p=[0.3, 0.3, 0.3, 0.08, 0.02])
    return [(int(rng.integers(3)), 1_000_000 * k, rng.bytes(int(size))) for k, size in enumerate(sizes)]


def _write_both(tmp_path: Path, stream: list[tuple[int, int, bytes]], batch: int) -> tuple[bytes, bytes, int]:
    """The .mcap of ``stream`` written by rosbags message by message and by ``write_batch`` in batches of
    ``batch`` (a description written alone first, a connection added between batches, as the recorder does),
    and the chunks the latter closed before the last."""
    store = bracing_typestore()
    files = []
    for name, writer in (
        ("one_by_one", Writer(tmp_path / "one_by_one" / "bag", version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)),
        ("batched", BagWriter(tmp_path / "batched" / "bag", version=BAG_VERSION)),
    ):
        writer.open()
        description = writer.add_connection("/robot_description", STRING, typestore=store)
        writer.write(description, 0, b"\x00\x01\x00\x00" + b"<robot/>")
        connections = [writer.add_connection(f"/t{k}", CLOCK, typestore=store) for k in range(2)]
        for start in range(0, len(stream), batch):
            if start == batch:
                connections.append(writer.add_connection("/late", VECTOR3_STAMPED, typestore=store))
            part = [m for m in stream[start : start + batch] if m[0] < len(connections)]
            if isinstance(writer, BagWriter):
                end = np.cumsum([len(data) for _, _, data in part])
                joined = np.frombuffer(b"".join(data for _, _, data in part), np.uint8)
                channels = np.array([connections[c].id for c, _, _ in part], np.uint16)
                writer.write_batch(channels, np.array([s for _, s, _ in part], np.int64), joined, end)
            else:
                for c, stamp, data in part:
                    writer.write(connections[c], stamp, data)
        chunks = len(cast(McapWriter, writer.storage).chunks)
        writer.close()
        files.append(
            (tmp_path / name / "bag" / "bag.mcap").read_bytes()
            + (tmp_path / name / "bag" / "metadata.yaml").read_bytes()
        )
    return files[0], files[1], chunks


@pytest.mark.parametrize(("n", "batch", "closed"), [(400, 100, 1), (3000, 700, 5), (50, 1, 0)])
def test_write_batch_writes_the_bag_rosbags_writes_message_by_message(
    tmp_path: Path, n: int, batch: int, closed: int
) -> None:
    stream = _stream(n, seed=n)
    one_by_one, batched, chunks = _write_both(tmp_path, stream, batch)
    assert chunks >= closed  # chunks closed mid-batch, at the message that takes one past MAX_CHUNK_BYTES
    assert batched == one_by_one
    with AnyReader([tmp_path / "batched" / "bag"]) as reader:
        read = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    assert len(read) == 1 + sum(1 for c, _, _ in stream[:batch] if c < 2) + sum(1 for m in stream[batch:])


# ----------------------------------------------------------------- the recorder's batch path, in process


@pytest.fixture
def rclpy_default() -> Iterator[None]:
    """rclpy initialised in this process, in a domain of its own (the recorder node joins the default context)."""
    import rclpy
    from ros_helpers import hold_test_domain

    rclpy.init(domain_id=hold_test_domain())
    yield
    rclpy.shutdown()


STATE_TOPICS = ["/joint_states", "/contact_wrench/elbow", "/contacts", "/motor_state", "/clock"]
OPTIONAL = {"/hand_orientation_error": 130, "/odom": 40}  # from this state on, after the state's messages


def _batches(states: int, per: int) -> list[SimpleNamespace]:
    """RecordBatch-like samples of a simulator: its per-state messages, then optional topics that start
    mid-run (one in the first batch, one in a later one), as ``RecordBatchPublisher`` packs them."""
    topics = [*STATE_TOPICS, *OPTIONAL]
    packer, out = BatchPacker(topics, per), []
    for k in range(states):
        for index, topic in enumerate(topics):
            if OPTIONAL.get(topic, 0) <= k:
                packer.add(index, stamped(k // 1000, (k % 1000) * 1_000_000, bytes([index]) * (8 + 3 * index)))
        if packer.state_done():
            batch = packer.take()
            out.append(
                SimpleNamespace(
                    node="/bracing_simulator",
                    sequence=batch.sequence,
                    topics=batch.topics,
                    topic_of=array("H", batch.topic_of),
                    end=array("I", batch.end),
                    data=array("B", batch.data),
                )
            )
    return out


def test_the_recorders_batches_make_the_bag_of_their_messages_one_by_one(tmp_path: Path, rclpy_default: None) -> None:
    """The same bag, message counts, last /clock and queued scene inputs whether the recorder writes a batch
    in bulk or each of its messages in turn (an optional topic's connection added at its first message)."""
    from bracing_recorder.recorder import Recorder

    batches = _batches(300, 100)
    seen = []
    for name in ("one_by_one", "batched"):
        writer = BagWriter(tmp_path / name / "bag", version=BAG_VERSION)
        writer.open()
        recorder = Recorder(writer, bracing_typestore(), contacts=["elbow"], from_batches=True)
        for batch in batches:
            if name == "batched":
                assert recorder._record_batch(batch) == len(batch.end)
            else:
                for topic, data in unpack(batch.topics, batch.topic_of, batch.end, bytes(batch.data)):
                    (recorder._write_optional if topic in OPTIONAL else recorder._write)(topic, data)
        writer.close()
        seen.append((dict(recorder.counts), list(recorder._scene_inputs), recorder._sim_time_ns))
        recorder.destroy_node()
    assert seen[1] == seen[0]
    assert seen[0][0]["/odom"] == 260 and seen[0][2] == 299_000_000
    assert (tmp_path / "batched" / "bag" / "bag.mcap").read_bytes() == (
        tmp_path / "one_by_one" / "bag" / "bag.mcap"
    ).read_bytes()


def test_a_batch_with_a_message_too_short_for_its_stamp_is_left_out_and_an_empty_one_is_harmless(
    tmp_path: Path, rclpy_default: None, capsys: pytest.CaptureFixture[str]
) -> None:
    from bracing_recorder.recorder import Recorder

    writer = BagWriter(tmp_path / "bag", version=BAG_VERSION)
    writer.open()
    recorder = Recorder(writer, bracing_typestore(), contacts=["elbow"], from_batches=True)
    batch = _batches(1, 1)[0]
    batch.data, batch.end = array("B", b"\x00\x01\x00\x00\x05"), array("I", [5])
    batch.topic_of = array("H", [0])
    assert recorder._record_batch(batch) == 0
    assert (
        "a record_batch from /bracing_simulator left out: message 0: 5 bytes, no header stamp"
        in capsys.readouterr().err
    )
    batch.sequence, batch.data, batch.end, batch.topic_of = 1, array("B"), array("I"), array("H")
    assert recorder._record_batch(batch) == 0  # an empty batch: nothing to write, nothing refused
    assert "left out" not in capsys.readouterr().err
    assert recorder.counts["/joint_states"] == 0
    writer.close()
    recorder.destroy_node()


class _Takes:
    """A recorder's waiter that hands out prepared takes, one per wait: lists of (subscription, sample)."""

    def __init__(self, takes: list[list[tuple[object, object]]]) -> None:
        self._takes = list(takes)

    def wait(self, timeout_sec: float) -> list[object]:
        del timeout_sec
        return []

    def take_ready(self, ready: list[object]) -> list[tuple[object, object]]:
        del ready
        return self._takes.pop(0) if self._takes else []


def _status(event: int, sim_time: float, text: str = "") -> bytes:
    """A run_status sample of the simulator (CDR bytes)."""
    from bracing_core.overrides import SIMULATOR
    from bracing_core.typestore import RUN_STATUS

    store = bracing_typestore()
    time_type = store.types["builtin_interfaces/msg/Time"]
    message = store.types[RUN_STATUS](time_type(sec=1, nanosec=0), SIMULATOR, event, sim_time, float("nan"), text)
    return bytes(store.serialize_cdr(message, RUN_STATUS))


def test_a_lockstep_bag_written_after_the_last_step_is_the_bag_written_as_it_came(
    tmp_path: Path, rclpy_default: None
) -> None:
    """``record(defer=True)`` writes nothing until the simulator's FINISHED, then the same bag byte for byte as
    ``record`` writing every take at once (warnings between batches in place), with its CPU share while it stepped."""
    from bracing_msgs.msg import RunStatus
    from bracing_recorder.recorder import Recorder

    batches = _batches(400, 100)
    files, counts = [], []
    for name, defer in (("as_it_came", False), ("deferred", True)):
        writer = BagWriter(tmp_path / name / "bag", version=BAG_VERSION)
        writer.open()
        recorder = Recorder(writer, bracing_typestore(), contacts=["elbow"], from_batches=True)
        assert recorder._batches is not None
        sim, status = recorder._batches, recorder._status
        takes: list[list[tuple[object, object]]] = [
            [(sim, batches[0]), (status, _status(RunStatus.WARNING, 0.05, "a warning"))],
            [(sim, batches[1])],
            [(status, _status(RunStatus.PROGRESS, 0.2)), (sim, batches[2])],
            [(status, _status(RunStatus.WARNING, 0.3, "another")), (status, _status(RunStatus.FINISHED, 0.399))],
            [(sim, batches[3])],
        ]
        recorder._waiter = _Takes(takes)  # type: ignore[assignment]
        for k in range(len(takes)):
            assert recorder.record(0.0, defer=defer) == len(takes[k])
            if k < 3:  # before FINISHED: kept (deferred), or written
                assert recorder.counts["/clock"] == (0 if defer else 100 * (k + 1))
        counts.append(dict(recorder.counts))
        share = recorder.stepping_cpu_share
        assert share is not None and share > 0
        writer.close()
        recorder.destroy_node()
        files.append((tmp_path / name / "bag" / "bag.mcap").read_bytes())
    assert counts[1] == counts[0] and counts[0]["/clock"] == 400 and counts[0]["/run_status"] == 2
    assert files[1] == files[0]
