"""Decode many CDR messages of one type at once into numpy columns (no rclpy needed).

rosbags' generated deserializer builds one Python object per message (~30 us each); the
messages of one topic of ours almost always share one byte layout (same strings, same
sequence lengths), so a layout is worked out once on a probe message and every message
that shares it is read column-wise with numpy.

``decode(typestore, msgtype, raws)`` returns one ``Layout`` per distinct layout, naming
the messages it holds by their index in ``raws``. Field paths are attribute paths of
rosbags' message objects: ``header.stamp.sec``, ``position[2]``,
``contacts[0].normal.x``; a sequence's or array's length is in ``lengths`` (``position`` -> 4), a
string is in ``strings`` (``name[1]`` -> "joint2"), a primitive is a numpy column in
``values`` (one value per message, dtype of the field: ``int32``, ``float64``, ``bool``...).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.typesys.store import Typestore

from bracing_core import cdr

MAX_PROBES = 16
"""Layouts tried per message size before each remaining message is its own probe: bounds the
vectorised comparisons when nearly every message differs (e.g. a counter in a string)."""


@dataclass
class Layout:
    """The messages (``index`` into the decoded list) that share one byte layout."""

    index: NDArray[np.intp]
    values: dict[str, NDArray[Any]] = field(default_factory=dict)
    strings: dict[str, str] = field(default_factory=dict)
    lengths: dict[str, int] = field(default_factory=dict)

    def texts(self, path: str) -> list[str]:
        """The strings of the string sequence (or array) at ``path``."""
        return [self.strings[f"{path}[{i}]"] for i in range(self.lengths[path])]


class _Probe(cdr.Walker):
    """Walks one message's bytes along its definition: where each primitive lies and which
    bytes (sequence lengths, strings) fix the layout."""

    def __init__(self, typestore: Typestore, data: bytes) -> None:
        super().__init__(typestore)
        self.data = data
        self.order = "<" if data[1] & 1 else ">"
        self.leaves: list[tuple[str, int, str]] = []  # path, offset, struct code
        self.fixed: list[int] = [0, 1]  # header bytes: representation and endianness
        self.strings: dict[str, str] = {}
        self.lengths: dict[str, int] = {}

    def _uint32(self) -> int:
        self.fixed.extend(range(self.offset, self.offset + 4))
        return int.from_bytes(self.data[self.offset : self.offset + 4], "little" if self.order == "<" else "big")

    def number(self, code: str, value: Any, path: str) -> None:
        self.leaves.append((path, self.offset, code))

    def numbers(self, code: str, values: Sequence[Any], count: int, path: str) -> None:
        size = cdr.SIZES[code]
        self.leaves += [(f"{path}[{i}]", self.offset + i * size, code) for i in range(count)]

    def string(self, value: Any, bound: int, path: str) -> int:
        size = self._uint32()  # includes the terminating NUL
        start = self.offset + 4
        self.fixed.extend(range(start, start + size))
        self.strings[path] = self.data[start : start + size - 1].decode()
        return 4 + size

    def length(self, value: Any, bound: int, path: str) -> int:
        return self._uint32()

    def elements(self, value: Any, count: int, path: str) -> Sequence[Any]:
        self.lengths[path] = count
        return [None] * count


def decode(
    typestore: Typestore, msgtype: str, raws: Sequence[bytes | memoryview], max_probes: int = MAX_PROBES
) -> list[Layout]:
    """The CDR messages ``raws`` (encapsulation header included) of ``msgtype``, column-wise.

    Every message is in exactly one returned Layout. Raises what ``typestore.deserialize_cdr``
    raises for a message it cannot decode.
    """
    out: list[Layout] = []
    sizes = np.fromiter((len(raw) for raw in raws), dtype=np.intp, count=len(raws))
    for size in np.unique(sizes):
        index = np.flatnonzero(sizes == size)
        rows = np.frombuffer(b"".join(raws[i] for i in index.tolist()), dtype=np.uint8).reshape(len(index), int(size))
        for _ in range(max_probes):
            if not len(index):
                break
            probe = _probe(typestore, msgtype, bytes(rows[0]))
            fixed = np.array(probe.fixed, dtype=np.intp)
            same = (rows[:, fixed] == rows[0, fixed]).all(axis=1)
            out.append(_columns(probe, index[same], rows if same.all() else rows[same]))
            index, rows = index[~same], rows[~same]
        # Too many layouts of this size: each remaining message is its own probe.
        for i, row in enumerate(rows):
            out.append(_columns(_probe(typestore, msgtype, bytes(row)), index[i : i + 1], rows[i : i + 1]))
    return out


def _probe(typestore: Typestore, msgtype: str, data: bytes) -> _Probe:
    # rosbags validates the probe (lengths, terminators, UTF-8, size) and raises as it would;
    # a message with the same size and the same layout bytes is then valid too.
    typestore.deserialize_cdr(data, msgtype)
    probe = _Probe(typestore, data)
    probe.message(msgtype, None)
    return probe


def _columns(probe: _Probe, index: NDArray[np.intp], rows: NDArray[np.uint8]) -> Layout:
    layout = Layout(index=index, strings=probe.strings, lengths=probe.lengths)
    buffer = np.ascontiguousarray(rows)
    for path, offset, code in probe.leaves:
        # A bool is read as a byte, then != 0 (rosbags' struct '?' is True for any non-zero byte).
        kind = "B" if code == "?" else code
        view = np.ndarray((len(rows),), probe.order + kind, buffer, offset, (rows.shape[1],))
        # Native byte order, like rosbags' values (a copy: the rows are freed).
        layout.values[path] = view != 0 if code == "?" else view.astype(kind)
    return layout


def column(layouts: Sequence[Layout], path: str, count: int) -> NDArray[Any]:
    """The primitive at ``path`` of every message, in message order (every layout must have it)."""
    first = layouts[0].values[path] if layouts else np.zeros(0)
    out = np.empty(count, dtype=first.dtype)
    for layout in layouts:
        out[layout.index] = layout.values[path]
    return out
