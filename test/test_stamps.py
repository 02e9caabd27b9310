"""One stamp conversion (bracing_core.stamps): exact both ways, and a CDR message's stamp read in the byte
order its encapsulation header gives (a big-endian writer's bytes read as big-endian)."""

from __future__ import annotations

import numpy as np
import pytest

from bracing_core import stamps
from bracing_core.typestore import CLOCK, JOINT_STATE, bracing_typestore


@pytest.mark.parametrize("t_ns", [0, 1, 999_999_999, 1_000_000_000, 1_700_000_000_123_456_789, -1, -1_500_000_000])
def test_nanoseconds_and_stamps_round_trip_exactly(t_ns: int) -> None:
    sec, nanosec = stamps.sec_nanosec(t_ns)
    assert 0 <= nanosec < stamps.NS_PER_S
    store = bracing_typestore()
    assert stamps.stamp_ns(store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)) == t_ns
    assert stamps.ns_of(sec, nanosec) == t_ns


def test_columns_convert_as_single_stamps() -> None:
    sec = np.array([0, 3, 1_700_000_000], dtype=np.int64)
    nanosec = np.array([5, 999_999_999, 123_456_789], dtype=np.int64)
    assert stamps.ns_of(sec, nanosec).tolist() == [
        stamps.ns_of(int(s), int(n)) for s, n in zip(sec, nanosec, strict=True)
    ]


@pytest.mark.parametrize("little_endian", [True, False])
@pytest.mark.parametrize("typename", [CLOCK, JOINT_STATE])
def test_cdr_stamp_honours_the_byte_order_flag(typename: str, little_endian: bool) -> None:
    store = bracing_typestore()
    t = store.types
    sec, nanosec = 1_700_000_123, 456_789_012
    time = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    if typename == CLOCK:
        msg = t[CLOCK](clock=time)
    else:
        empty = np.zeros(0)
        msg = t[JOINT_STATE](t["std_msgs/msg/Header"](time, "base"), ["j"], empty, empty, empty)
    data = bytes(store.serialize_cdr(msg, typename, little_endian=little_endian))
    assert data[1] == (1 if little_endian else 0)  # CDR_LE / CDR_BE
    assert stamps.cdr_stamp_ns(data) == sec * stamps.NS_PER_S + nanosec
    assert stamps.cdr_stamp_seconds(data) == stamps.stamp_seconds(sec * stamps.NS_PER_S + nanosec)


def test_seconds_are_the_laws() -> None:
    """Seconds from nanoseconds are the engine's (the law's time, bit for bit), ns * 1e-9."""
    for t_ns in (1, 1_000_000, 1_234_567_891, 86_400_000_000_001):
        assert stamps.stamp_seconds(t_ns) == t_ns * 1e-9
