"""Batches of a node's messages for the recorder: packing, checked unpacking, and the CDR bytes."""

from __future__ import annotations

import re

import pytest

from bracing_core.record_batch import BatchError, BatchPacker, unpack

TOPICS = ["/joint_states", "/clock", "/motor_command"]


def _messages(states: int) -> list[tuple[int, bytes]]:
    """(topic index, bytes) as a node publishes them: three of different lengths per state."""
    return [(j, bytes([k, j]) * (j + 1 + k % 3)) for k in range(states) for j in range(len(TOPICS))]


def test_a_batch_gives_back_every_message_in_order_under_its_topic() -> None:
    packer = BatchPacker(TOPICS, size=4)
    sent = _messages(4)
    full = []
    for k in range(4):
        for index, data in sent[3 * k : 3 * k + 3]:
            packer.add(index, data)
        full.append(packer.state_done())
    assert full == [False, False, False, True]
    batch = packer.take()
    assert batch.sequence == 0 and len(packer) == 0
    assert unpack(batch.topics, batch.topic_of, batch.end, batch.data) == [(TOPICS[i], d) for i, d in sent]
    packer.add(0, b"x")
    assert packer.take().sequence == 1  # one more per batch: a gap tells the recorder one was lost


@pytest.mark.parametrize(
    ("topic_of", "end", "data", "what"),
    [
        ([0, 1], [2], b"ab", "2 topic indices for 1 messages"),
        ([3], [2], b"ab", "message 0: topic index 3, but the batch names 3 topics"),
        ([0], [5], b"ab", "message 0: its bytes end at 5, after 0 (data holds 2)"),
        ([0, 1], [2, 1], b"ab", "message 1: its bytes end at 1, after 2"),
        ([0, 1], [1, 1], b"ab", "message 1: its bytes end at 1, after 1"),
        ([0], [1], b"ab", "1 bytes of data after the last message"),
    ],
)
def test_a_batch_whose_fields_do_not_fit_is_refused_whole(
    topic_of: list[int], end: list[int], data: bytes, what: str
) -> None:
    with pytest.raises(BatchError, match=re.escape(what)):
        unpack(TOPICS, topic_of, end, data)


def test_a_batch_holds_at_least_one_state() -> None:
    with pytest.raises(ValueError, match="at least one state"):
        BatchPacker(TOPICS, size=0)


def test_the_encoder_writes_what_rclpy_reads_back() -> None:
    """report_encoders.RecordBatchEncoder (rosbags' serialiser) against rclpy's own deserialiser."""
    from rclpy.serialization import deserialize_message

    from bracing_msgs.msg import RecordBatch
    from bracing_ros.report_encoders import RecordBatchEncoder

    packer = BatchPacker(TOPICS, size=3)
    for index, data in _messages(3):
        packer.add(index, data)
    batch = packer.take()
    msg = deserialize_message(
        RecordBatchEncoder("/ns/bracing_simulator").encode(
            batch.sequence, batch.topics, batch.topic_of, batch.end, batch.data
        ),
        RecordBatch,
    )
    assert (msg.node, msg.sequence, list(msg.topics)) == ("/ns/bracing_simulator", 0, TOPICS)
    assert (list(msg.topic_of), list(msg.end), bytes(msg.data)) == (batch.topic_of, batch.end, batch.data)
