"""Message stamps (builtin_interfaces/Time: ``sec``, ``nanosec``) and nanoseconds, one conversion each way.

Nanoseconds are the exact form (an int64, as rclpy's ``Time.nanoseconds``); seconds as a float are
``bracing_engine.stamp_seconds`` (``ns * 1e-9``), the law's and the rollout's time, bit for bit.
"""

from __future__ import annotations

import struct
from typing import Any

from bracing_engine import stamp_seconds

__all__ = ["NS_PER_S", "cdr_stamp_ns", "cdr_stamp_seconds", "ns_of", "sec_nanosec", "stamp_ns", "stamp_seconds"]

NS_PER_S = 1_000_000_000
_CDR_STAMP = {True: struct.Struct("<iI"), False: struct.Struct(">iI")}
"""builtin_interfaces/Time after the 4-byte encapsulation header, by the header's little-endian flag."""


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces/Time (rosbags' or rclpy's) in nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_of(sec: Any, nanosec: Any) -> Any:
    """Nanoseconds of ``sec`` and ``nanosec`` as they are (ints, or int64 arrays: a bag's columns)."""
    return sec * NS_PER_S + nanosec


def sec_nanosec(t_ns: int) -> tuple[int, int]:
    """A stamp's (sec, nanosec) for ``t_ns`` [ns] (nanosec in [0, 10^9), as rclpy's Time.to_msg)."""
    return divmod(t_ns, NS_PER_S)


def cdr_stamp_ns(data: bytes) -> int:
    """Stamp [ns] of a message's CDR bytes whose first field is a builtin_interfaces/Time (every header
    message, rosgraph_msgs/Clock), read in the byte order the encapsulation header's flag gives."""
    sec, nanosec = _CDR_STAMP[bool(data[1] & 1)].unpack_from(data, 4)
    return int(sec) * NS_PER_S + int(nanosec)


def cdr_stamp_seconds(data: bytes) -> float:
    """``cdr_stamp_ns`` in seconds (``stamp_seconds``)."""
    return stamp_seconds(cdr_stamp_ns(data))
