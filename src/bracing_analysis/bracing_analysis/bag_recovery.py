"""A bag cut short, recovered as ``ros2 bag reindex`` does (``recover_bag``): for bracing-pair and bracing-report.

A recorder killed mid-run (SIGKILL, the OOM killer, a power cut) leaves its mcap file without its end: no
summary section, no footer, and no metadata.yaml beside it (rosbags writes them when the bag closes), so
rosbags and rosbag2 refuse the bag. The records before the cut are whole. ``recover_bag`` reads them one by
one from the file's start (an mcap needs no summary to be read that way), keeps every complete record
(schemas, channels, messages; a chunk of messages only if all of it was written, its checksum right) and
writes the bag anew through rosbags' rosbag2 Writer, with its summary and a metadata.yaml: every message
kept on its topic, type and QoS offer, with its timestamp, in file order.

What is lost with the process: the messages it had not written yet (rosbags' writer holds up to 1 MiB of
messages, its open chunk, in memory: up to ~0.85 s of a lockstep run of the paper arm, whose streams take
1.2 MB per second of sim time) and the bag's custom_data
(the recorder's notes: scenario, surfaces, task axes), written on close; ``recover_bag`` keeps those of an
existing metadata.yaml and takes others from its caller (bracing-pair knows its run's).
"""

from __future__ import annotations

import os
import shutil
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import BinaryIO, Literal

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import ReaderError, StoragePlugin, Writer, WriterError
from rosbags.rosbag2.storage_mcap import decompress, get_qos
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

from bracing_analysis.bag_events import custom_data

MCAP_MAGIC = b"\x89MCAP0\r\n"
BAG_VERSION: Literal[8] = 8  # the recorder's rosbag2 metadata version (read by every Jazzy rosbag2)
UNKNOWN_TYPE_HASH = "RIHS01_" + "0" * 64
"""A schema whose definition rosbags cannot parse keeps its messages, with this type hash."""

_SCHEMA, _CHANNEL, _MESSAGE, _CHUNK, _DATA_END = 0x03, 0x04, 0x05, 0x06, 0x0F
_RECORD_HEAD = struct.Struct("<BQ")  # opcode, body length
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct("<QQQI")  # start time, end time, uncompressed size, CRC-32
_IDL_SEPARATOR = "=" * 80 + "\n"


class RecoveryError(RuntimeError):
    """The bag is not one cut short, or cannot be rewritten."""


class _Cut(Exception):
    """A record that cannot be whole (a chunk whose data does not check): the cut is there."""


@dataclass(frozen=True)
class Recovered:
    """What ``recover_bag`` kept."""

    path: Path  # the bag directory, whole again
    messages: int
    topics: int
    last_ns: int | None  # the latest message timestamp kept [ns] (None: no message)
    cut_bytes: int  # the bytes after the last complete record, left out

    def last_s(self) -> float | None:
        """The latest timestamp kept [s] (the run's sim time, for a bag of a lockstep run)."""
        return None if self.last_ns is None else self.last_ns * 1e-9

    def describe(self) -> str:
        end = f" up to t = {self.last_ns * 1e-9:.3f} s" if self.last_ns is not None else ""
        return f"{self.messages} messages on {self.topics} topics{end}"


def has_end(mcap: Path) -> bool:
    """Whether the file ends as a closed mcap does (its footer's magic)."""
    try:
        with mcap.open("rb") as stream:
            if stream.seek(0, os.SEEK_END) < 2 * len(MCAP_MAGIC):
                return False
            stream.seek(-len(MCAP_MAGIC), os.SEEK_END)
            return stream.read() == MCAP_MAGIC
    except OSError:
        return False


def cut_files(bag: Path) -> list[Path]:
    """The mcap files of a bag directory cut short (no metadata.yaml, or a file without its end), else []."""
    files = sorted(bag.glob("*.mcap")) if bag.is_dir() else []
    if files and (not (bag / "metadata.yaml").exists() or not all(has_end(f) for f in files)):
        return files
    return []


def recover_bag(bag: Path, notes: Mapping[str, str] | None = None) -> Recovered:
    """Rewrite the bag directory ``bag`` cut short (``cut_files``) whole: one mcap with its summary and a
    metadata.yaml, its custom_data an existing metadata.yaml's updated with ``notes``. The cut files are
    replaced. Raises RecoveryError if ``bag`` is not cut short or cannot be rewritten."""
    files = cut_files(bag)
    if not files:
        raise RecoveryError(f"{bag}: not a bag cut short (it has metadata.yaml and every mcap file its end)")
    staging = bag.parent / f".{bag.name}.recovering"
    shutil.rmtree(staging, ignore_errors=True)  # a recovery interrupted before (the cut files are still there)
    writer = Writer(staging / bag.name, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
    for key, value in {**custom_data(bag), **(notes or {})}.items():
        writer.set_custom_data(key, value)
    try:
        writer.open()
        rewriter = _Rewriter(writer)
        cut = sum(rewriter.copy(file) for file in files)
        writer.close()
        _replace(bag, staging / bag.name, files)
    except (OSError, ValueError, RuntimeError, WriterError) as exc:
        writer.abort()
        shutil.rmtree(staging, ignore_errors=True)
        raise RecoveryError(f"cannot recover bag {bag}: {exc}") from exc
    return Recovered(bag, rewriter.count, len(rewriter.written), rewriter.last_ns, cut)


def recover_if_cut(bag: Path) -> Recovered | None:
    """``recover_bag`` if ``bag`` is a directory cut short; None if it is whole (or not a bag directory)."""
    return recover_bag(bag) if cut_files(bag) else None


def _replace(bag: Path, staged: Path, cut: list[Path]) -> None:
    """The staged bag's files into ``bag`` in place of the cut ones; metadata.yaml last (the bag is whole once
    it is there: an interrupted replacement is recovered again)."""
    mcap = bag / f"{bag.name}.mcap"
    os.replace(staged / mcap.name, mcap)
    for file in cut:
        if file != mcap:
            file.unlink(missing_ok=True)
    os.replace(staged / "metadata.yaml", bag / "metadata.yaml")
    shutil.rmtree(staged.parent, ignore_errors=True)


def _records(stream: BinaryIO, size: int) -> Iterator[tuple[int, bytes]]:
    """(opcode, body) of each whole record from the stream's position up to ``size`` bytes; stops at the
    first one cut (its length is checked against what is there before it is read)."""
    while stream.tell() + _RECORD_HEAD.size <= size:
        opcode, length = _RECORD_HEAD.unpack(stream.read(_RECORD_HEAD.size))
        if length > size - stream.tell():
            return
        yield opcode, stream.read(length)


def _string(body: bytes, at: int) -> tuple[str, int]:
    """An mcap string (uint32 length, UTF-8) at ``at``; it and the offset after it."""
    (length,) = struct.unpack_from("<I", body, at)
    return body[at + 4 : at + 4 + length].decode(), at + 4 + length


def _chunk_records(body: bytes) -> Iterator[tuple[int, bytes]]:
    """The records of a whole chunk, decompressed and checked (_Cut if its data does not check)."""
    try:
        _, _, size, crc = _CHUNK_HEAD.unpack_from(body)
        compression, at = _string(body, _CHUNK_HEAD.size)
        (compressed_size,) = struct.unpack_from("<Q", body, at)
        data = decompress(body[at + 8 : at + 8 + compressed_size], compression, size, crc)
    except Exception as exc:  # a chunk that does not check: struct, lz4, zstd and rosbags raise their own kinds
        raise _Cut() from exc
    return _records(BytesIO(data), len(data))


def _type_hash(name: str, encoding: str, definition: str) -> str:
    """The RIHS01 hash of a schema's type, from its definition (as rosbags' AnyReader builds its types)."""
    store = get_typestore(Stores.EMPTY)
    try:
        if encoding == "ros2msg":
            store.register(get_types_from_msg(definition, name))
        else:  # ros2idl: the type's IDL, then each dependency's, after a separator line and an "IDL: name" line
            for part in definition.split(_IDL_SEPARATOR)[1:]:
                store.register(get_types_from_idl(part.split("\n", 1)[1]))
        return store.hash_rihs01(name)
    except Exception:  # a definition rosbags cannot parse: the messages are kept all the same
        return UNKNOWN_TYPE_HASH


class _Rewriter:
    """The whole records of cut mcap files, written to a rosbag2 Writer as they are read."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer
        self.schemas: dict[int, tuple[str, str, str]] = {}  # id: (type name, encoding, definition)
        self.channels: dict[int, Connection] = {}  # the file's channel id: the connection written
        self.written: dict[tuple[str, str, str, tuple[Qos, ...]], Connection] = {}
        self.count = 0
        self.last_ns: int | None = None

    def copy(self, mcap: Path) -> int:
        """Every whole record of ``mcap`` (the channel ids are the file's own); the bytes cut after them."""
        self.channels = {}
        with mcap.open("rb") as stream:
            size = stream.seek(0, os.SEEK_END)
            stream.seek(0)
            magic = stream.read(len(MCAP_MAGIC))
            if magic != MCAP_MAGIC[: len(magic)]:
                raise RecoveryError(f"{mcap}: not an mcap file")
            end = stream.tell()
            try:
                for opcode, body in _records(stream, size):
                    if opcode == _DATA_END:
                        return 0  # the summary follows: the file was whole
                    self._take(opcode, body)
                    end = stream.tell()
            except _Cut:
                pass
            return size - end

    def _take(self, opcode: int, body: bytes) -> None:
        if opcode == _CHUNK:
            for inner in _chunk_records(body):
                self._take(*inner)
        elif opcode == _MESSAGE:
            channel, _, log_time, _ = _MESSAGE_HEAD.unpack_from(body)
            connection = self.channels.get(channel)
            if connection is not None:
                self.writer.write(connection, log_time, body[_MESSAGE_HEAD.size :])
                self.count += 1
                self.last_ns = log_time if self.last_ns is None else max(self.last_ns, log_time)
        elif opcode == _SCHEMA:
            (key,) = struct.unpack_from("<H", body)
            name, at = _string(body, 2)
            encoding, at = _string(body, at)
            self.schemas[key] = (name, encoding, _string(body, at)[0])
        elif opcode == _CHANNEL:
            self._add_channel(body)

    def _add_channel(self, body: bytes) -> None:
        key, schema = struct.unpack_from("<HH", body)
        topic, at = _string(body, 4)
        encoding, at = _string(body, at)
        (length,) = struct.unpack_from("<I", body, at)
        try:
            qos = tuple(get_qos(body[at + 4 : at + 4 + length]))
        except (ReaderError, ValueError):  # an offer rosbags cannot parse: the messages are kept, without it
            qos = ()
        if key in self.channels or schema not in self.schemas:
            return  # a channel repeated, or one without a schema (no type to write it under)
        name, schema_encoding, definition = self.schemas[schema]
        same = (topic, name, encoding, qos)
        if same not in self.written:  # two channels alike are one connection of the bag (the Writer's rule)
            self.written[same] = self.writer.add_connection(
                topic,
                name,
                msgdef=definition,
                rihs01=_type_hash(name, schema_encoding, definition),
                serialization_format=encoding,
                offered_qos_profiles=qos,
            )
        self.channels[key] = self.written[same]
