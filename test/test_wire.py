"""bracing_sim.wire: the hand-built CDR bytes are exactly what rclpy reads and writes.

Every encoder's bytes are decoded by rclpy (the rosidl typesupport) into the values put in,
and every decoder reads rclpy's bytes back; random values, several sizes, empty sequences.
"""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from bracing_msgs.msg import Contacts, ControllerState, MotorCommand, MotorState
from bracing_sim import wire

RNG = np.random.default_rng(7)
NAME_SETS = [[], ["j"], ["joint1", "joint2", "joint3", "joint4"], [f"link_{k}_joint" for k in range(7)], ["ß", "关节"]]


def _stamp_ns() -> int:
    return int(RNG.integers(0, 2**31 - 1)) * 1_000_000_000 + int(RNG.integers(0, 999_999_999))


def _ns(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _xyz(p: object) -> list[float]:
    return [p.x, p.y, p.z]  # type: ignore[attr-defined]


@pytest.mark.parametrize("names", NAME_SETS)
def test_joint_state_round_trips_through_rclpy(names: list[str]) -> None:
    n = len(names)
    stamp, q, dq, tau = _stamp_ns(), RNG.normal(size=n), RNG.normal(size=n), RNG.normal(size=n)
    msg = deserialize_message(wire.JointStateEncoder(names).encode(stamp, q, dq, tau), JointState)
    assert _ns(msg.header.stamp) == stamp and msg.header.frame_id == ""
    assert list(msg.name) == names
    assert list(msg.position) == q.tolist() and list(msg.velocity) == dq.tolist() and list(msg.effort) == tau.tolist()

    back = wire.decode_joint_state(serialize_message(msg))
    assert (back.stamp_ns, back.name) == (stamp, names)
    assert back.position.tolist() == q.tolist() and back.velocity.tolist() == dq.tolist()
    assert back.effort.tolist() == tau.tolist()


def test_joint_state_decoder_reads_any_layout() -> None:
    """Other publishers' JointStates: other frame ids, unequal (empty) sequences."""
    msg = JointState(name=["b", "a", "c"], position=[1.0, 2.0, 3.0], velocity=[], effort=[4.5])
    msg.header.frame_id = "base_link_frame"
    msg.header.stamp = Time(sec=12, nanosec=34)
    back = wire.decode_joint_state(serialize_message(msg))
    assert back.stamp_ns == 12_000_000_034 and back.name == ["b", "a", "c"]
    assert back.position.tolist() == [1.0, 2.0, 3.0] and back.velocity.size == 0 and back.effort.tolist() == [4.5]


def test_clock_and_wrench() -> None:
    stamp = _stamp_ns()
    clock = deserialize_message(wire.ClockEncoder().encode(stamp), Clock)
    assert _ns(clock.clock) == stamp
    force = RNG.normal(size=3)
    wrench = deserialize_message(wire.WrenchStampedEncoder("world").encode(stamp, force), WrenchStamped)
    assert _ns(wrench.header.stamp) == stamp and wrench.header.frame_id == "world"
    assert _xyz(wrench.wrench.force) == force.tolist() and _xyz(wrench.wrench.torque) == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("count", [0, 1, 3])
def test_contacts(count: int) -> None:
    names, frames = [f"c{k}" for k in range(count)], [f"link_{k}_frame" for k in range(count)]
    reports = [
        wire.ContactReport(
            active=bool(k % 2 == 0),
            position=RNG.normal(size=3),
            normal=RNG.normal(size=3),
            normal_force=float(RNG.normal()),
            friction_force=float(RNG.normal()),
            slip_velocity=RNG.normal(size=3),
            residual=float(RNG.normal()),
        )
        for k in range(count)
    ]
    stamp = _stamp_ns()
    msg = deserialize_message(wire.ContactsEncoder(names, frames).encode(stamp, reports), Contacts)
    assert _ns(msg.header.stamp) == stamp and msg.header.frame_id == "world"
    assert len(msg.contacts) == count
    for got, name, frame, want in zip(msg.contacts, names, frames, reports, strict=True):
        assert (got.name, got.frame, got.active) == (name, frame, want.active)
        assert _xyz(got.position) == want.position.tolist() and _xyz(got.normal) == want.normal.tolist()
        assert (got.normal_force, got.friction_force, got.residual) == (
            want.normal_force,
            want.friction_force,
            want.residual,
        )
        assert _xyz(got.slip_velocity) == want.slip_velocity.tolist()


@pytest.mark.parametrize("names", NAME_SETS)
def test_motor_state(names: list[str]) -> None:
    n = len(names)
    v, i, p = RNG.normal(size=n), RNG.normal(size=n), RNG.normal(size=n)
    energies = (1.5, -2.25, 3.0e-7)
    stamp = _stamp_ns()
    msg = deserialize_message(wire.MotorStateEncoder(names).encode(stamp, v, i, p, energies), MotorState)
    assert _ns(msg.header.stamp) == stamp and list(msg.name) == names
    assert list(msg.voltage) == v.tolist() and list(msg.current) == i.tolist() and list(msg.power) == p.tolist()
    assert (msg.energy_consumed, msg.energy_net, msg.copper_loss) == energies


@pytest.mark.parametrize("names", NAME_SETS)
@pytest.mark.parametrize("mode", [MotorCommand.VOLTAGE, MotorCommand.TORQUE])
def test_motor_command_round_trips_through_rclpy(names: list[str], mode: int) -> None:
    value, stamp = RNG.normal(size=len(names)), _stamp_ns()
    msg = deserialize_message(wire.MotorCommandEncoder(names, mode).encode(stamp, value), MotorCommand)
    assert _ns(msg.header.stamp) == stamp and msg.mode == mode
    assert list(msg.name) == names and list(msg.value) == value.tolist()

    back = wire.decode_motor_command(serialize_message(msg))
    assert (back.stamp_ns, back.mode, back.name, back.value.tolist()) == (stamp, mode, names, value.tolist())


@pytest.mark.parametrize("contacts", [[], ["elbow"], ["elbow", "wrist"]])
@pytest.mark.parametrize("n", [0, 4])
def test_controller_state(contacts: list[str], n: int) -> None:
    p = len(contacts)
    hand_desired, hand_actual = RNG.normal(size=3), RNG.normal(size=3)
    force, brace_desired, brace_actual = RNG.normal(size=p), RNG.normal(size=(p, 3)), RNG.normal(size=(p, 3))
    command, stamp = RNG.normal(size=n), _stamp_ns()
    data = wire.ControllerStateEncoder(contacts, n).encode(
        stamp, hand_desired, hand_actual, force, brace_desired, brace_actual, command, 2.5e-5
    )
    msg = deserialize_message(data, ControllerState)
    assert _ns(msg.header.stamp) == stamp and msg.header.frame_id == "world"
    assert _xyz(msg.hand_desired) == hand_desired.tolist() and _xyz(msg.hand_actual) == hand_actual.tolist()
    assert list(msg.contact_name) == contacts and list(msg.desired_normal_force) == force.tolist()
    assert [_xyz(b) for b in msg.brace_desired] == brace_desired.tolist()
    assert [_xyz(b) for b in msg.brace_actual] == brace_actual.tolist()
    assert list(msg.command) == command.tolist() and msg.compute_time == 2.5e-5


def test_big_endian_cdr_is_read() -> None:
    # A MotorCommand written big-endian by hand: stamp 5 s 6 ns, frame "", mode 1, ["a"], [2.0].
    data = (
        b"\x00\x00\x00\x00"
        + (5).to_bytes(4, "big")
        + (6).to_bytes(4, "big")
        + (1).to_bytes(4, "big")
        + b"\x00"
        + b"\x01"
        + b"\x00\x00"
        + (1).to_bytes(4, "big")
        + (2).to_bytes(4, "big")
        + b"a\x00"
        + b"\x00\x00"
        + (1).to_bytes(4, "big")
        + np.array([2.0], dtype=">f8").tobytes()
    )
    back = wire.decode_motor_command(data)
    assert (back.stamp_ns, back.mode, back.name, back.value.tolist()) == (5_000_000_006, 1, ["a"], [2.0])


def test_bad_bytes_raise_decode_errors() -> None:
    # (rclpy's own bytes end with a few unused bytes; these end where the content does.)
    good = wire.JointStateEncoder(["a", "b"]).encode(5, np.ones(2), np.ones(2), np.ones(2))
    for cut in range(4, len(good)):
        with pytest.raises(wire.DecodeError):
            wire.decode_joint_state(good[:cut])
    with pytest.raises(wire.UnsupportedEncoding):
        wire.decode_joint_state(b"\x00\x07\x00\x00" + good[4:])  # XCDR2
    with pytest.raises(wire.UnsupportedEncoding):
        wire.decode_motor_command(b"")
    huge = bytearray(good)
    huge[12:16] = (2**31).to_bytes(4, "little")  # frame_id length far past the end
    with pytest.raises(wire.DecodeError):
        wire.decode_joint_state(bytes(huge))


def test_layout_decoders_agree_with_the_general_ones() -> None:
    """The decoders' quick path (the expected layout) and their general path read the same values."""
    names = ["joint1", "joint2", "joint3", "joint4"]
    states = wire.JointStateDecoder(names)
    commands = wire.MotorCommandDecoder(names, MotorCommand.VOLTAGE)
    q, dq, tau = RNG.normal(size=4), RNG.normal(size=4), RNG.normal(size=4)
    same_layout = JointState(name=names, position=q.tolist(), velocity=dq.tolist(), effort=tau.tolist())
    other_layout = JointState(name=names[::-1], position=q.tolist(), velocity=dq.tolist(), effort=[])
    other_layout.header.frame_id = "base"
    for msg in (same_layout, other_layout):
        msg.header.stamp = Time(sec=3, nanosec=4)
        data = serialize_message(msg)  # with rclpy's extra bytes at the end
        quick, general = states.decode(data), wire.decode_joint_state(data)
        assert (quick.stamp_ns, quick.name) == (general.stamp_ns, general.name) == (3_000_000_004, list(msg.name))
        for a, b in ((quick.position, general.position), (quick.velocity, general.velocity)):
            assert a.tolist() == b.tolist()
        assert quick.effort.tolist() == general.effort.tolist() == list(msg.effort)
    for mode, order in ((MotorCommand.VOLTAGE, names), (MotorCommand.TORQUE, names), (MotorCommand.VOLTAGE, names[:3])):
        command = MotorCommand(mode=mode, name=order, value=RNG.normal(size=len(order)).tolist())
        data = serialize_message(command)
        quick, general = commands.decode(data), wire.decode_motor_command(data)
        assert (quick.mode, quick.name, quick.value.tolist()) == (general.mode, general.name, general.value.tolist())
        assert (quick.mode, quick.name, quick.value.tolist()) == (mode, order, list(command.value))
