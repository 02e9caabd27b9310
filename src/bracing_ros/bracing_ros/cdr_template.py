"""Byte templates of a message: its CDR bytes laid out from its definition, constants written once and
numeric slots packed per message with one ``struct`` call (the fast path of :mod:`bracing_ros.wire`'s
lockstep messages and of the recorder's derived scene).

Layouts come from the message definitions (through the rosbags typestore of
:mod:`bracing_core.typestore`, walked by :mod:`bracing_core.cdr`); none is written here by hand.
The bytes are plain CDR (XCDR1) with the little-endian encapsulation header, as rclpy's.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from operator import itemgetter
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Nodetype

from bracing_core import cdr
from bracing_core.cdr import FieldDesc
from bracing_core.typestore import bracing_typestore

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


@dataclass(frozen=True)
class PerMessage:
    """Marks a field of a template spec whose numbers are packed per message.

    On a number, an array of numbers or a message of numbers (``header.stamp``): all of it.
    On a sequence: ``count`` elements (the length is fixed in the template).
    """

    count: int | None = None


PER_MESSAGE = PerMessage()

_DEFAULT: Any = object()  # a field the spec leaves out: zero / empty


class Template:
    """A message's bytes with constant parts fixed and numeric slots filled per message.

    The whole message is one ``struct`` format: the constant runs as ``Ns`` items, each slot
    as its numbers (alignment padding inside a slot as ``x``).
    """

    def __init__(self, chunks: Sequence[bytes], slot_formats: Sequence[str], slot_counts: Sequence[int]) -> None:
        if len(chunks) != len(slot_formats) + 1 or len(slot_formats) != len(slot_counts):
            raise ValueError("a template alternates constant chunks and slots, chunks first and last")
        fmt = "".join(f"{len(chunk)}s{slot}" for chunk, slot in zip(chunks, slot_formats, strict=False))
        self._struct = struct.Struct(f"<{fmt}{len(chunks[-1])}s")
        self._first, self._rest = bytes(chunks[0]), tuple(bytes(c) for c in chunks[1:])
        self.slot_counts = tuple(slot_counts)
        # Where each constant and each slot sits among the unpacked items.
        constant_items, self._slices, k = [0], [], 1
        for count in slot_counts:
            self._slices.append(slice(k, k + count))
            k += count
            constant_items.append(k)
            k += 1
        self._constants = itemgetter(*constant_items)
        self.data = self.fill(*([0] * count for count in slot_counts))
        self._expected = self._constants(self._struct.unpack(self.data))

    @property
    def size(self) -> int:
        return self._struct.size

    def fill(self, *values: Sequence[float | int]) -> bytes:
        """The message with slot k holding ``values[k]`` (a sequence of numbers).

        The total number of values is checked (``struct.error``); how they split among the
        slots is the caller's.
        """
        items: list[object] = [self._first]
        for value, chunk in zip(values, self._rest, strict=True):
            items += value
            items.append(chunk)
        return self._struct.pack(*items)

    def layout(self) -> tuple[bytes, list[tuple[int, int]], list[int], str]:
        """The template as offsets, for code that fills or reads it without ``struct`` (bracing_rcl's C++):
        its bytes with every slot zero, the constant runs (offset, length), and each value's offset and
        ``struct`` code, in ``fill``'s order."""
        constants: list[tuple[int, int]] = []
        offsets: list[int] = []
        codes, offset = "", 0
        for count_text, code in re.findall(r"(\d*)([a-zA-Z?])", self._struct.format[1:]):
            count = int(count_text or 1)
            if code == "s":
                if count:
                    constants.append((offset, count))
                offset += count
            elif code == "x":
                offset += count
            else:
                size = struct.calcsize("<" + code)
                offsets += range(offset, offset + size * count, size)
                codes += code * count
                offset += size * count
        return self.data, constants, offsets, codes

    def read(self, data: bytes) -> list[tuple[Any, ...]] | None:
        """The slots' values if ``data`` has this layout (the same constants), else None.

        Bytes past the layout's end are ignored: rclpy's own messages carry a few.
        """
        if len(data) < self._struct.size:
            return None
        items = self._struct.unpack_from(data)
        if self._constants(items) != self._expected:
            return None
        return [items[s] for s in self._slices]


def derive_template(typename: str, spec: Mapping[str, Any], typestore: Typestore | None = None) -> Template:
    """A template of ``typename`` laid out from its definition in ``typestore``.

    ``spec`` mirrors the message, a mapping per (nested) message: a field maps to its
    constant value (a string, number, list, or mapping for a nested message) or to
    :class:`PerMessage` (filled by :meth:`Template.fill`, one slot per marker, in definition
    order). Fields left out are zero / empty. Per-message parts hold numbers only.
    """
    builder = _SpecBuilder(typestore if typestore is not None else bracing_typestore())
    builder.message(typename, spec, f"{typename}.")
    return builder.build()


def message_template(
    typename: str, message: Any, varies: Callable[[str, FieldDesc], bool], typestore: Typestore
) -> tuple[Template, list[str]]:
    """A template of the layout of ``message`` (a message object of ``typestore``), and its slots' paths.

    Its strings, lengths and other values are fixed; a field (or an array's or a sequence's
    element) where ``varies(path, field desc)`` is a slot (a sequence: of ``message``'s
    length). Paths are field names, ``a.b.c``, without element indices (every element's
    alike); the answer lists each slot's, in definition order.
    """
    builder = _MessageBuilder(typestore, varies)
    builder.message(typename, message)
    return builder.build(), builder.paths


@dataclass
class _Slot:
    start: int  # offset of its first number (after the alignment before it)
    end: int  # past its last number
    tokens: list[str] = field(default_factory=list)  # struct format items: numbers, and padding between them
    count: int = 0  # numbers


class _Builder(cdr.Walker):
    """Writes a template's bytes along the definition: constants, and slots for the per-message parts.

    Subclasses say where the values come from (``member``) and which fields are filled per
    message (``marker``).
    """

    def __init__(self, store: Typestore) -> None:
        super().__init__(store)
        self.buffer = bytearray(cdr.ENCAPSULATION_LE)
        self.slots: list[_Slot] = []
        self._marker: PerMessage | None = None  # the per-message part being walked
        self._slot: _Slot | None = None  # its slot, from its first number on

    def marker(self, value: Any, desc: FieldDesc, path: str) -> PerMessage | None:
        raise NotImplementedError

    def field(self, desc: FieldDesc, value: Any, path: str) -> None:
        """One field: constant ``value`` (or its default), or a slot for a :class:`PerMessage`."""
        marker = None if self._marker is not None else self.marker(value, desc, path)
        if marker is None:
            super().field(desc, value, path)
            return
        kind, arg = desc
        if kind == Nodetype.SEQUENCE:
            if marker.count is None:
                raise ValueError(f"{path}: a sequence filled per message needs its length (PerMessage(count))")
            if arg[1] and marker.count > arg[1]:
                raise ValueError(f"{path}: at most {arg[1]} elements, not {marker.count}")
        elif marker.count is not None:
            raise ValueError(f"{path}: only a sequence takes a length")
        self._marker, self._slot = marker, None
        super().field(desc, marker, path)
        if self._slot is None:  # no number (an empty sequence): an empty slot
            self.slots.append(_Slot(self.offset, self.offset))
        self._marker = None

    def _pad(self) -> None:
        """The alignment padding the walk has just moved past, written."""
        self.buffer += bytes(self.offset - len(self.buffer))

    def number(self, code: str, value: Any, path: str) -> None:
        if self._marker is None:
            self._pad()
            self.buffer += struct.pack("<" + code, 0 if value is _DEFAULT else value)
        else:
            self.numbers(code, (), 1, path)

    def numbers(self, code: str, values: Sequence[Any], count: int, path: str) -> None:
        self._pad()
        if self._marker is None:
            self.buffer += struct.pack(f"<{count}{code}", *[0 if v is _DEFAULT else v for v in values])
            return
        slot = self._slot
        if slot is None:  # the slot starts here, after the alignment (part of the constant before it)
            slot = self._slot = _Slot(self.offset, self.offset)
            self.slots.append(slot)
        elif self.offset > slot.end:
            slot.tokens.append(f"{self.offset - slot.end}x")
        slot.tokens.append(f"{count}{code}")
        slot.count += count
        slot.end = self.offset + cdr.SIZES[code] * count
        self.buffer += bytes(slot.end - self.offset)

    def string(self, value: Any, bound: int, path: str) -> int:
        if self._marker is not None:
            raise ValueError(f"{path}: a string in a per-message part (its length would vary)")
        text = "" if value is _DEFAULT else value
        if not isinstance(text, str):
            raise TypeError(f"{path}: a string field needs a str, not {text!r}")
        if bound and len(text) > bound:
            raise ValueError(f"{path}: a string of at most {bound} characters, not {len(text)}")
        data = text.encode() + b"\x00"
        self._pad()
        self.buffer += struct.pack("<I", len(data)) + data
        return 4 + len(data)

    def length(self, value: Any, bound: int, path: str) -> int:
        if self._marker is None:
            count = 0 if value is _DEFAULT else len(value)
            if bound and count > bound:
                raise ValueError(f"{path}: at most {bound} elements, not {count}")
        elif value is self._marker:
            count = self._marker.count or 0
        else:
            raise ValueError(f"{path}: a sequence inside a per-message part (its length would vary)")
        self._pad()
        self.buffer += struct.pack("<I", count)
        return count

    def elements(self, value: Any, count: int, path: str) -> Sequence[Any]:
        if self._marker is not None or value is _DEFAULT:
            return [_DEFAULT] * count
        elements = list(value)
        if len(elements) != count:
            raise ValueError(f"{path}: an array of {count}, not {len(elements)}")
        return elements

    def build(self) -> Template:
        chunks, end = [], 0
        for slot in self.slots:
            chunks.append(bytes(self.buffer[end : slot.start]))
            end = slot.end
        chunks.append(bytes(self.buffer[end:]))
        return Template(chunks, ["".join(slot.tokens) for slot in self.slots], [slot.count for slot in self.slots])


class _SpecBuilder(_Builder):
    """Values from a :func:`derive_template` spec; its :class:`PerMessage` markers are the slots."""

    def message(self, typename: str, value: Any, path: str = "") -> None:
        if self._marker is None:
            spec = {} if value is _DEFAULT else value
            if not isinstance(spec, Mapping):
                raise TypeError(f"{path.rstrip('.')}: a nested message needs a mapping of its fields, not {spec!r}")
            unknown = set(spec) - {name for name, _ in self.store.fielddefs[typename][1]}
            if unknown:
                raise ValueError(f"{typename} has no field {', '.join(sorted(unknown))}")
        super().message(typename, value, path)

    def member(self, value: Any, name: str, path: str) -> Any:
        if self._marker is not None or value is _DEFAULT:
            return _DEFAULT
        return value.get(name, _DEFAULT)

    def marker(self, value: Any, desc: FieldDesc, path: str) -> PerMessage | None:
        return value if isinstance(value, PerMessage) else None


class _MessageBuilder(_Builder):
    """Values from a message object; the fields ``varies`` names are the slots (``paths``)."""

    def __init__(self, store: Typestore, varies: Callable[[str, FieldDesc], bool]) -> None:
        super().__init__(store)
        self.varies = varies
        self.paths: list[str] = []

    def item(self, path: str, index: int) -> str:
        return path  # every element's field alike

    def member(self, value: Any, name: str, path: str) -> Any:
        return _DEFAULT if self._marker is not None else getattr(value, name)

    def marker(self, value: Any, desc: FieldDesc, path: str) -> PerMessage | None:
        if not self.varies(path, desc):
            return None
        self.paths.append(path)
        return PerMessage(len(value)) if desc[0] == Nodetype.SEQUENCE else PER_MESSAGE
