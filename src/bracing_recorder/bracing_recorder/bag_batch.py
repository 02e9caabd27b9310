"""The recorder's bag writer: rosbags' rosbag2 ``Writer`` (MCAP, no compression) that also writes many
messages at once (``BagWriter.write_batch``, numpy; no rclpy).

Why: rosbags builds each MCAP record field by field in Python, ~10 us a message with the message index
its chunk writes for it; a lockstep state brings ~7 messages (record_batch), ~40 us of a niced process on
the two cores the nodes share. Here a whole batch's Message records are built at once and appended to
the open chunk, and a chunk's message index is written in one piece: byte for byte the bag that
``Writer.write`` makes message by message (the same records, chunk boundaries, indices, statistics and
metadata; a test compares the files). It extends the pinned rosbags' ``McapWriter``, which that test guards.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping
from io import BytesIO
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import (
    McapWriter,
    PendingChunk,
    write_record,
    write_string,
    write_uint16,
    write_uint32,
    write_uint64,
)

if TYPE_CHECKING:
    from rosbags.rosbag2.writer import StorageWriter  # a Protocol, for type checkers only

RECORD_HEADER = np.dtype(
    [
        ("opcode", "u1"),
        ("length", "<u8"),
        ("channel", "<u2"),
        ("sequence", "<u4"),
        ("log_time", "<u8"),
        ("publish_time", "<u8"),
    ]
)
"""An MCAP Message record up to its data (31 bytes, packed), as ``McapWriter.write`` writes it."""
MESSAGE_OPCODE = 0x05
RECORD_FIELDS = RECORD_HEADER.itemsize - 9  # a record's length counts what follows its opcode and length
MAX_CHUNK_BYTES = 2**20
"""rosbags' McapWriter closes its chunk after the message that takes it past this many bytes."""
NS_PER_S = 1_000_000_000
STAMPED_MIN_BYTES = 12
"""A message whose first field is a builtin_interfaces/Time: the encapsulation header (4 bytes) and the stamp."""


def message_starts(end: np.ndarray) -> np.ndarray:
    """Where each message starts, of messages back to back ending at ``end`` (the first at 0)."""
    start = np.zeros(len(end), np.int64)
    start[1:] = end[:-1]
    return start


def header_stamps_ns(data: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The header stamp [ns] of each message whose CDR bytes start at ``start`` in ``data`` (uint8; its
    first field a builtin_interfaces/Time, at least ``STAMPED_MIN_BYTES``), in the byte order its
    encapsulation header gives: ``stamps.cdr_stamp_ns`` of each."""
    stamp = np.ascontiguousarray(data[start[:, None] + np.arange(4, STAMPED_MIN_BYTES)])  # sec int32, nanosec uint32
    little = (data[start + 1] & 1).astype(bool)
    sec = np.where(little, stamp.view("<i4")[:, 0], stamp.view(">i4")[:, 0]).astype(np.int64)
    nanosec = np.where(little, stamp.view("<u4")[:, 1], stamp.view(">u4")[:, 1]).astype(np.int64)
    return sec * NS_PER_S + nanosec


def message_records(channels: np.ndarray, stamps_ns: np.ndarray, data: np.ndarray, end: np.ndarray) -> bytes:
    """The MCAP Message records of messages back to back in ``data`` (uint8) up to ``end``, on ``channels``
    at ``stamps_ns`` (their log and publish time), as ``McapWriter.write`` writes each."""
    n = len(end)
    start = message_starts(end)
    headers = np.zeros(n, RECORD_HEADER)
    headers["opcode"] = MESSAGE_OPCODE
    headers["length"] = end - start + RECORD_FIELDS
    headers["channel"] = channels
    headers["log_time"] = stamps_ns
    headers["publish_time"] = stamps_ns
    header_bytes = (
        (np.arange(n) * RECORD_HEADER.itemsize + start)[:, None] + np.arange(RECORD_HEADER.itemsize)
    ).ravel()
    out = np.empty(int(end[-1]) + n * RECORD_HEADER.itemsize, np.uint8)
    in_data = np.ones(len(out), bool)
    in_data[header_bytes] = False
    out[header_bytes] = headers.view(np.uint8)
    out[in_data] = data[: end[-1]]
    return out.tobytes()


class BulkMcapWriter(McapWriter):
    """rosbags' MCAP storage writer with ``write_batch`` and a chunk index written in one piece."""

    def write_batch(self, channels: np.ndarray, stamps_ns: np.ndarray, data: np.ndarray, end: np.ndarray) -> None:
        """``write`` of each message, in order (see ``BagWriter.write_batch``)."""
        first = 0
        while first < len(end):
            base = int(end[first - 1]) if first else 0
            ends = end[first:] - base
            record_end = self.chunk.bio.tell() + ends + RECORD_HEADER.itemsize * np.arange(1, len(ends) + 1)
            # the chunk ends with the message that takes it past its size, as in ``write``
            last = first + min(int(np.searchsorted(record_end, MAX_CHUNK_BYTES, side="right")), len(ends) - 1)
            self._append(channels[first : last + 1], stamps_ns[first : last + 1], data[base:], ends[: last + 1 - first])
            if self.chunk.bio.tell() > MAX_CHUNK_BYTES:
                self.close_chunk()
            first = last + 1

    def _append(self, channels: np.ndarray, stamps_ns: np.ndarray, data: np.ndarray, end: np.ndarray) -> None:
        """Messages into the open chunk, with the bookkeeping of ``write`` (index, statistics, time range)."""
        chunk = self.chunk
        record_start = chunk.bio.tell() + np.arange(len(end)) * RECORD_HEADER.itemsize + message_starts(end)
        chunk.bio.write(message_records(channels, stamps_ns, data, end))
        earliest, latest = int(stamps_ns.min()), int(stamps_ns.max())
        chunk.message_start_time = min(earliest, chunk.message_start_time)
        chunk.message_end_time = max(latest, chunk.message_end_time)
        self.message_start_time = min(earliest, self.message_start_time)
        self.message_end_time = max(latest, self.message_end_time)
        present, first_at, counts = np.unique(channels, return_index=True, return_counts=True)
        entries = np.stack([stamps_ns, record_start], axis=1).astype("<u8")
        for k in np.argsort(first_at, kind="stable"):  # the index's channels in the order of their first message
            # one (n, 2) array of (log time, offset) among write's (log time, offset) tuples: see close_chunk
            chunk.msgs[int(present[k])].append(entries[channels == present[k]])  # type: ignore[arg-type]
            self.channel_stats[int(present[k])] += int(counts[k])

    def close_chunk(self) -> None:
        """``McapWriter.close_chunk``, each channel's message index written in one piece (its entries are
        ``write``'s (log time, offset) tuples and ``_append``'s arrays of them)."""
        chunk = self.chunk
        rec = BytesIO()
        write_uint64(rec, chunk.message_start_time)
        write_uint64(rec, chunk.message_end_time)
        write_uint64(rec, chunk.bio.tell())
        write_uint32(rec, 0)
        compressed = self.compressor(chunk.bio.getvalue())
        write_string(rec, self.compression)
        write_uint64(rec, len(compressed))
        rec.write(compressed)
        chunk_start = self.bio.tell()
        write_record(self.bio, 0x06, rec)
        chunk_end = self.bio.tell()
        offsets: list[tuple[int, int]] = []
        for cid, msgs in chunk.msgs.items():
            offsets.append((cid, self.bio.tell()))
            index = b"".join(np.asarray(entry, "<u8").tobytes() for entry in msgs)  # (log time, offset) each
            rec = BytesIO()
            write_uint16(rec, cid)
            write_uint32(rec, len(index))
            rec.write(index)
            write_record(self.bio, 0x07, rec)
        rec = BytesIO()
        for value in (chunk.message_start_time, chunk.message_end_time, chunk_start, chunk_end - chunk_start):
            write_uint64(rec, value)
        write_uint32(rec, len(offsets) * 10)
        for cid, offset in offsets:
            write_uint16(rec, cid)
            write_uint64(rec, offset)
        write_uint64(rec, self.bio.tell() - chunk_end)
        write_string(rec, self.compression)
        write_uint64(rec, len(compressed))
        write_uint64(rec, chunk.bio.tell())
        self.chunks.append(rec)
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))


class BagWriter(Writer):
    """rosbags' rosbag2 ``Writer`` (MCAP storage) with ``write_batch``."""

    STORAGE_PLUGINS: Mapping[StoragePlugin, type[StorageWriter]] = {
        **Writer.STORAGE_PLUGINS,
        StoragePlugin.MCAP: BulkMcapWriter,
    }

    def __init__(self, path: Path | str, *, version: Literal[8, 9]) -> None:
        super().__init__(path, version=version, storage_plugin=StoragePlugin.MCAP)

    def write_batch(self, channels: np.ndarray, stamps_ns: np.ndarray, data: np.ndarray, end: np.ndarray) -> None:
        """Messages back to back in ``data`` (uint8) up to ``end`` (exclusive ends, the first from 0), message k
        on the connection whose id is ``channels[k]`` at ``stamps_ns[k]`` (>= 0): the bag ``write`` of each
        in turn makes."""
        if not isinstance(self.storage, BulkMcapWriter):
            raise RuntimeError("the bag is not open")
        if not len(end):
            return
        if stamps_ns.min() < 0:
            raise ValueError(f"a message stamped {stamps_ns.min()} ns: an MCAP log time is unsigned")
        self.storage.write_batch(channels, stamps_ns, data, end)
        present, counts = np.unique(channels, return_counts=True)
        for channel, count in zip(present.tolist(), counts.tolist(), strict=True):
            self.counts[channel] += count
        self.min_timestamp = min(int(stamps_ns.min()), self.min_timestamp)
        self.max_timestamp = max(int(stamps_ns.max()), self.max_timestamp)
