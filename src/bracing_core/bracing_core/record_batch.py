"""Batches of a node's per-step messages for the recorder (``bracing_msgs/RecordBatch``), ROS-free.

Why: a recorder that subscribes to every per-step topic costs the lockstep loop one DDS delivery
per message to a third process, with its wake-ups on a two-core machine: measured (paper
arm, 4 s runs) a subscriber that only took the messages and dropped them slowed the pair from 2.47x
to 1.56x real time, as much as the recorder itself (1.85x), and one that woke only every 50 ms
still to 1.73x. Handed over in batches, the recorder gets one sample per ``size`` states.

``BatchPacker`` collects a node's messages (topic, CDR bytes) in the order they were published;
``unpack`` checks a received batch and gives the messages back, in that order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


class BatchError(ValueError):
    """A received batch that cannot be unpacked (says what is wrong with it)."""


@dataclass(frozen=True)
class Batch:
    """One batch's fields, as ``RecordBatch`` has them."""

    sequence: int
    topics: list[str]
    topic_of: list[int]  # per message: index into topics
    end: list[int]  # per message: where its bytes end in data
    data: bytes


class BatchPacker:
    """A node's messages since the last batch; ``state_done`` says when it holds ``size`` states."""

    def __init__(self, topics: Sequence[str], size: int) -> None:
        if size < 1:
            raise ValueError(f"a batch holds at least one state, not {size}")
        self.topics = list(topics)
        self.size = size
        self.sequence = 0
        self._states = 0
        self._topic_of: list[int] = []
        self._chunks: list[bytes] = []
        self._end: list[int] = []

    def add(self, topic_index: int, data: bytes) -> None:
        """One message published on ``topics[topic_index]`` (its CDR bytes)."""
        self._topic_of.append(topic_index)
        self._chunks.append(data)
        self._end.append((self._end[-1] if self._end else 0) + len(data))

    def state_done(self) -> bool:
        """One more state's messages are in; whether the batch is now full (``take`` it)."""
        self._states += 1
        return self._states >= self.size

    def __len__(self) -> int:
        """Messages waiting."""
        return len(self._topic_of)

    def take(self) -> Batch:
        """The waiting messages as one batch (the next sequence number); the packer starts afresh."""
        batch = Batch(self.sequence, self.topics, self._topic_of, self._end, b"".join(self._chunks))
        self.sequence += 1
        self._states, self._topic_of, self._chunks, self._end = 0, [], [], []
        return batch


def batch_layout(
    topics: Sequence[str], topic_of: Sequence[int], end: Sequence[int], data_size: int
) -> tuple[np.ndarray, np.ndarray]:
    """A received batch's ``topic_of`` and ``end`` as int64 arrays, checked against its ``topics`` and its
    ``data_size`` bytes of data; ``BatchError`` (what is wrong with its first bad message) if they do not fit
    together (nothing of such a batch is used)."""
    if len(topic_of) != len(end):
        raise BatchError(f"{len(topic_of)} topic indices for {len(end)} messages")
    index = np.asarray(topic_of, np.int64)
    stop = np.asarray(end, np.int64)
    start = np.concatenate(([0], stop[:-1]))
    bad_index = (index < 0) | (index >= len(topics))
    bad_stop = (stop <= start) | (stop > data_size)
    bad = np.flatnonzero(bad_index | bad_stop)
    if len(bad):
        k = int(bad[0])
        if bad_index[k]:
            raise BatchError(f"message {k}: topic index {index[k]}, but the batch names {len(topics)} topics")
        raise BatchError(f"message {k}: its bytes end at {stop[k]}, after {start[k]} (data holds {data_size})")
    used = int(stop[-1]) if len(stop) else 0
    if used != data_size:
        raise BatchError(f"{data_size - used} bytes of data after the last message")
    return index, stop


def unpack(topics: Sequence[str], topic_of: Sequence[int], end: Sequence[int], data: bytes) -> list[tuple[str, bytes]]:
    """(topic, CDR bytes) of each message of a received batch, in order; ``BatchError`` if its fields
    do not fit together (``batch_layout``)."""
    index, stop = batch_layout(topics, topic_of, end, len(data))
    view = memoryview(data)
    return [
        (topics[i], bytes(view[a:b]))
        for i, a, b in zip(index.tolist(), [0, *stop[:-1].tolist()], stop.tolist(), strict=True)
    ]
