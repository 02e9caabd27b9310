"""What one subscribed message may carry, and how a refusal quotes it (no ROS).

A node checks a message's sizes (``MessageLimits``: max_message_elements, max_name_length) before any
work per element, so no single message can stall its loop; every check after that is linear. Raw CDR
bytes are checked from their sequence and string length fields alone (``check_cdr_sizes``), before
their elements are decoded. A refusal quotes at most a few names, each cut short (``quote_names``),
so that its log line stays short whatever the message held.
"""

from __future__ import annotations

import re
import struct
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bracing_core import cdr

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

QUOTED_NAMES = 3
"""Names a refusal quotes at most (the rest are counted)."""
QUOTED_CHARACTERS = 40
"""Characters of a quoted name at most (a longer one is cut, with an ellipsis)."""
SIZE_KIND = "too-large"
"""The kind (rate limit) of a refusal for size."""


class SizeError(ValueError):
    """A message larger than the limits allow; ``kind`` is ``SIZE_KIND``."""

    kind = SIZE_KIND


def shorten(text: str, limit: int = QUOTED_CHARACTERS) -> str:
    """``text`` cut to ``limit`` characters, with an ellipsis and the length if cut."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text)} characters)"


def quote_names(names: Sequence[str], shown: int = QUOTED_NAMES) -> str:
    """The first ``shown`` of ``names`` quoted (each shortened), and a count of the rest:
    "['a', 'b', 'c'] and 99997 more"."""
    head = "[" + ", ".join(repr(shorten(str(n))) for n in names[:shown]) + "]"
    rest = len(names) - shown
    return head if rest <= 0 else f"{head} and {rest} more"


def duplicated(names: Iterable[str]) -> list[str]:
    """The names that appear more than once, sorted (linear in the names, then a sort of the duplicates)."""
    return sorted(name for name, count in Counter(names).items() if count > 1)


@dataclass(frozen=True)
class MessageLimits:
    """max_message_elements and max_name_length of a node's configuration."""

    max_elements: int = 10000
    max_name_length: int = 256

    @classmethod
    def of(cls, config: Any) -> MessageLimits:
        """A node's (a SimulatorConfig's or a ControllerConfig's: both have the two parameters)."""
        return cls(config.max_message_elements, config.max_name_length)

    def check_count(self, field: str, count: int) -> None:
        """Raise SizeError if the sequence ``field`` ("name", "effort") holds more than max_elements."""
        if count > self.max_elements:
            raise SizeError(f"{field}: {count} elements, more than max_message_elements ({self.max_elements})")

    def check_name(self, field: str, name: str) -> None:
        """Raise SizeError if the string ``field`` ("header.frame_id") is longer than max_name_length."""
        if len(name) > self.max_name_length:
            raise SizeError(
                f"{field}: {len(name)} characters ({shorten(name)!r}), more than max_name_length "
                f"({self.max_name_length})"
            )


DEFAULT_LIMITS = MessageLimits()
"""The parameters' defaults."""


def check_cdr_sizes(store: Typestore, typename: str, data: bytes, limits: MessageLimits) -> None:
    """Raise SizeError if the plain-CDR bytes of a ``typename`` hold a sequence longer than max_elements
    or a string longer than max_name_length, read from their length fields only (the elements are
    not decoded); stops at the first. Bytes cut short or another encapsulation: nothing said here
    (the decoder says what is wrong with them)."""
    if len(data) < cdr.HEADER_SIZE or data[0] != 0 or data[1] not in (0, 1):
        return
    if len(data) - cdr.HEADER_SIZE <= min(limits.max_elements, limits.max_name_length):
        return  # too short to hold a longer string, or a sequence of more (1-byte) elements: no walk needed
    try:
        _SizeScan(store, data, limits).message(typename, None)
    except struct.error:  # cut short: the decoder's to report
        return


class _SizeScan(cdr.Walker):
    """Walks the bytes' length fields along the definition; raises SizeError at the first over a limit."""

    def __init__(self, store: Typestore, data: bytes, limits: MessageLimits) -> None:
        super().__init__(store)
        self.data, self.limits = data, limits
        self.uint32 = struct.Struct("<I" if data[1] == 1 else ">I").unpack_from

    def number(self, code: str, value: Any, path: str) -> None:
        pass

    def numbers(self, code: str, values: Sequence[Any], count: int, path: str) -> None:
        pass

    def string(self, value: Any, bound: int, path: str) -> int:
        size = self.uint32(self.data, self.offset)[0]  # its bytes, the terminating NUL included
        if size - 1 > self.limits.max_name_length:
            limit = self.limits.max_name_length
            raise SizeError(f"{_field(path)}: a string of {size - 1} bytes, more than max_name_length ({limit})")
        return 4 + size

    def length(self, value: Any, bound: int, path: str) -> int:
        count: int = self.uint32(self.data, self.offset)[0]
        self.limits.check_count(_field(path), count)
        return count


def _field(path: str) -> str:
    """A field's path without element indices: "layout.dim[3].label" -> "layout.dim.label"."""
    return re.sub(r"\[\d+\]", "", path)
