"""A ``bracing_msgs/RecordBatch`` into the recorder's bag in bulk (``bag_batch``): each message under its own topic,
as if it had come on it, the bag byte for byte the one written message by message (test_bag_batch).

``BatchWriting`` is a part of ``recorder.Recorder``: the bag, its connections and counts and the scene's queue are
the recorder's (``_open_bag``); these are the methods that put a batch's messages among them.
"""

from __future__ import annotations

import sys
from collections import deque
from typing import Any

import numpy as np
from rosbags.interfaces import Connection
from rosbags.typesys.store import Typestore

from bracing_core.record_batch import BatchError, batch_layout
from bracing_recorder.bag_batch import STAMPED_MIN_BYTES, BagWriter, header_stamps_ns, message_starts
from bracing_recorder.scene import SceneBuilder


class BatchWriting:
    """The recorder's batch path (``Recorder`` sets every attribute named here)."""

    writer: BagWriter
    typestore: Typestore
    counts: dict[str, int]
    scene: SceneBuilder | None
    _next_batch: dict[str, int]  # per node: the sequence number its next batch should have
    _recorded: dict[str, tuple[Connection, str]]  # resolved topic: its connection, its role
    _optional: dict[str, str]  # resolved optional per-state topic: its type name
    _optional_connections: dict[str, Connection]
    _sim_time_ns: int
    _scene_roles: set[str]
    _scene_inputs: deque[tuple[str, bytes]]

    def _record_batch(self, batch: Any) -> int:
        """Write a RecordBatch's messages (``batch``: the message, or any object with its fields), each under its
        own topic, in bulk; the count written (0 for a batch that cannot be unpacked, or that names a topic
        this recorder does not record)."""
        expected = self._next_batch.get(batch.node, 0)
        if batch.sequence != expected:
            lost = f"{batch.sequence - expected} batch(es)" if batch.sequence > expected else "a batch out of order"
            print(f"recorder: error: {lost} from {batch.node} lost (sequence {batch.sequence})", file=sys.stderr)
        self._next_batch[batch.node] = batch.sequence + 1
        raw = bytes(batch.data)
        try:
            topic_of, end = batch_layout(batch.topics, batch.topic_of, batch.end, len(raw))
            unknown = sorted({t for t in batch.topics if t not in self._recorded and t not in self._optional})
            if unknown:
                raise BatchError(f"it names topics this recorder does not record: {', '.join(unknown)}")
            sizes = end - message_starts(end)
            if len(short := np.flatnonzero(sizes < STAMPED_MIN_BYTES)):
                raise BatchError(f"message {short[0]}: {sizes[short[0]]} bytes, no header stamp")
        except BatchError as exc:
            print(f"recorder: error: a record_batch from {batch.node} left out: {exc}", file=sys.stderr, flush=True)
            return 0
        self._write_batch(list(batch.topics), topic_of, raw, end)
        return len(end)

    def _write_batch(self, topics: list[str], topic_of: np.ndarray, raw: bytes, end: np.ndarray) -> None:
        """A batch's messages (``topics[topic_of[k]]``, back to back in ``raw`` up to ``end``) into the bag in
        bulk, as ``_write`` and ``_write_optional`` would one by one (an optional topic's connection added
        at its first message, as there), at their header stamps; their counts, the last /clock, the scene's inputs."""
        data = np.frombuffer(raw, np.uint8)
        starts = message_starts(end)
        stamps = np.maximum(header_stamps_ns(data, starts), 0)
        first = 0
        for at, topic in self._first_optional(topics, topic_of):
            self._write_span(topics, topic_of[first:at], stamps[first:at], data, end[:at], first)
            self._optional_connections[topic] = self.writer.add_connection(
                topic, self._optional[topic], typestore=self.typestore
            )
            self.counts[topic] = 0
            first = at
        self._write_span(topics, topic_of[first:], stamps[first:], data, end, first)
        for index, count in enumerate(np.bincount(topic_of, minlength=len(topics)).tolist()):
            if count:
                self.counts[topics[index]] += count
        roles = [self._recorded[t][1] if t in self._recorded else "" for t in topics]
        if "/clock" in roles and len(clocks := np.flatnonzero(topic_of == roles.index("/clock"))):
            self._sim_time_ns = int(stamps[clocks[-1]])
        if self.scene is not None:
            wanted = np.flatnonzero(np.array([role in self._scene_roles for role in roles])[topic_of])
            spans = zip(starts[wanted].tolist(), end[wanted].tolist(), strict=True)
            inputs = zip([roles[i] for i in topic_of[wanted].tolist()], [raw[a:b] for a, b in spans], strict=True)
            self._scene_inputs.extend(inputs)

    def _first_optional(self, topics: list[str], topic_of: np.ndarray) -> list[tuple[int, str]]:
        """(message index, topic) of the first message of each optional topic not yet in the bag, in order."""
        firsts = []
        for index, topic in enumerate(topics):
            if topic in self._optional and topic not in self._optional_connections:
                at = np.flatnonzero(topic_of == index)
                if len(at):
                    firsts.append((int(at[0]), topic))
        return sorted(firsts)

    def _write_span(
        self, topics: list[str], topic_of: np.ndarray, stamps: np.ndarray, data: np.ndarray, end: np.ndarray, first: int
    ) -> None:
        """A batch's messages from ``first`` up to the last of ``end`` into the bag (``topic_of`` and ``stamps``
        theirs), every topic among them in the bag."""
        # an optional topic not in the bag yet has no message here (0 stands for its connection)
        ids = np.array([self._connection_id(t) for t in topics], np.uint16)
        base = int(end[first - 1]) if first else 0
        self.writer.write_batch(ids[topic_of], stamps, data[base:], end[first:] - base)

    def _connection_id(self, topic: str) -> int:
        """The bag connection id of a recorded or optional topic (resolved name; 0: an optional one not yet
        in the bag)."""
        if topic in self._recorded:
            return self._recorded[topic][0].id
        connection = self._optional_connections.get(topic)
        return connection.id if connection is not None else 0
