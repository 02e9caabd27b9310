"""The CDR layout of a message, walked along its definition in a rosbags typestore.

One type table, one alignment rule, one traversal for the three users that work with message
bytes directly: the byte templates of :mod:`bracing_ros.cdr_template` (writing), the column-wise bag
read of :mod:`bracing_analysis.columns` (reading) and, through wire, the recorder's scene.

The layout is rosbags' and rclpy's: plain CDR (XCDR1) after a 4-byte encapsulation header,
each primitive aligned to its size counted from the end of that header; a string or a
sequence is a ``uint32`` length (4-aligned) then its bytes or elements; an empty array or
sequence aligns nothing.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Nodetype

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

FieldDesc = Any
"""rosbags' FieldDesc: (Nodetype, argument) tuples nested; a union mypy cannot narrow by kind."""

HEADER_SIZE = 4
"""The encapsulation header; CDR alignment counts from its end."""
ENCAPSULATION_LE = b"\x00\x01\x00\x00"
"""Plain CDR, little endian."""

STRUCT_CODES: dict[str, str] = {  # its size is its alignment; also its numpy dtype (np.dtype(code))
    "bool": "?",
    "byte": "b",  # signed, as rosbags reads and writes it
    "char": "B",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
"""A ROS 2 primitive (``string`` aside) -> its ``struct`` format character."""

SIZES = {code: struct.calcsize(code) for code in set(STRUCT_CODES.values())}
"""A struct format character -> its size in bytes (and CDR alignment)."""


def struct_code(base: str, path: str) -> str:
    """The struct format character of the primitive ``base`` (ValueError if CDR here has none)."""
    try:
        return STRUCT_CODES[base]
    except KeyError:
        raise ValueError(f"{path}: type {base} is not supported") from None


def numbers_only(store: Typestore, desc: FieldDesc) -> bool:
    """A number, or numbers only (an array of them, a message of them): a fixed size, no string, no sequence."""
    kind, arg = desc
    if kind == Nodetype.BASE:
        return arg[0] in STRUCT_CODES
    if kind == Nodetype.NAME:
        return all(numbers_only(store, sub) for _, sub in store.fielddefs[arg][1])
    if kind == Nodetype.ARRAY:
        return numbers_only(store, arg[0])
    return False


class Walker:
    """Walks a message along its definition in CDR order, ``offset`` at each field's bytes.

    The walker owns the order and the alignment; a subclass says what the bytes are through
    the hooks, each called at the field's aligned offset (the walker then moves past it):

    - ``member(value, name, path)``: the value of field ``name`` of a message's ``value``;
    - ``number(code, value, path)``: one primitive;
    - ``numbers(code, values, count, path)``: ``count`` (> 0) primitives in a row, an array's
      or a sequence's;
    - ``string(value, bound, path)``: a string at its length field; answers its size in
      bytes, the length field included;
    - ``length(value, bound, path)``: a sequence's element count, at its length field;
    - ``elements(value, count, path)``: the values of an array's or a sequence's elements.

    Paths are attribute paths of the message: ``header.stamp.sec``, ``contacts[0].normal.x``
    (``item`` makes an element's).
    """

    def __init__(self, store: Typestore) -> None:
        self.store = store
        self.offset = HEADER_SIZE

    def align(self, size: int) -> int:
        """Moves to the next multiple of ``size`` (counted from the header's end); answers the padding."""
        pad = -(self.offset - HEADER_SIZE) % size
        self.offset += pad
        return pad

    def message(self, typename: str, value: Any, path: str = "") -> None:
        """The fields of ``typename``; ``path`` is the message's own with a trailing dot (or empty)."""
        for name, desc in self.store.fielddefs[typename][1]:
            self.field(desc, self.member(value, name, path + name), path + name)

    def field(self, desc: FieldDesc, value: Any, path: str) -> None:
        kind, arg = desc
        if kind == Nodetype.BASE:
            base, bound = arg
            if base == "string":
                self.align(4)
                self.offset += self.string(value, bound, path)
            else:
                code = struct_code(base, path)
                size = SIZES[code]
                self.align(size)
                self.number(code, value, path)
                self.offset += size
        elif kind == Nodetype.NAME:
            self.message(arg, value, path + ".")
        else:  # ARRAY (its size in the definition) or SEQUENCE (its size in the bytes)
            sub, bound = arg
            if kind == Nodetype.SEQUENCE:
                self.align(4)
                count = self.length(value, bound, path)
                self.offset += 4
            else:
                count = bound
            values = self.elements(value, count, path)
            if not count:
                return
            if sub[0] == Nodetype.BASE and sub[1][0] != "string":
                code = struct_code(sub[1][0], path)
                size = SIZES[code]
                self.align(size)
                self.numbers(code, values, count, path)
                self.offset += size * count
            else:
                for i, element in enumerate(values):
                    self.field(sub, element, self.item(path, i))

    def item(self, path: str, index: int) -> str:
        return f"{path}[{index}]"

    # -- hooks

    def member(self, value: Any, name: str, path: str) -> Any:
        return None

    def number(self, code: str, value: Any, path: str) -> None:
        raise NotImplementedError

    def numbers(self, code: str, values: Sequence[Any], count: int, path: str) -> None:
        raise NotImplementedError

    def string(self, value: Any, bound: int, path: str) -> int:
        raise NotImplementedError

    def length(self, value: Any, bound: int, path: str) -> int:
        raise NotImplementedError

    def elements(self, value: Any, count: int, path: str) -> Sequence[Any]:
        return [None] * count
