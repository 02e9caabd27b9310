"""CDR bytes of the messages a lockstep step sends and receives, without rclpy's message classes.

Why: rclpy moves every message through its generated Python class (type-checked setters,
then a conversion to C and back). For the few messages a step sends, that costs more than
the DDS write itself, and it sits on the lockstep loop's critical path. Their layout is
fixed for a whole run (joint and contact names do not change), so an encoder is a byte
template built once, whose numeric fields are packed in place; ``Publisher.publish``
accepts the bytes as they are. Decoders read any valid message of their type.

The bytes are what rclpy itself produces: plain CDR (XCDR1) with the little-endian
encapsulation header, alignment relative to the end of that header. The tests check every
encoder and decoder against ``rclpy.serialization``. Encapsulations other than plain CDR
raise :class:`UnsupportedEncoding`, so the caller can fall back to rclpy.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bracing_sim.core.types import Vector

_HEADER_SIZE = 4  # encapsulation header; CDR alignment counts from its end
_ENCAPSULATION_LE = b"\x00\x01\x00\x00"


class DecodeError(ValueError):
    """Bytes that are not a valid message of the expected type."""


class UnsupportedEncoding(DecodeError):
    """Valid-looking data in an encapsulation these decoders do not read (not plain CDR)."""


# ----------------------------------------------------------------------------- encoding


class _Layout:
    """Builds a byte template: constant parts written now, numeric fields left as slots."""

    def __init__(self) -> None:
        self.buffer = bytearray(_ENCAPSULATION_LE)
        self.slots: list[tuple[int, struct.Struct]] = []

    def _align(self, size: int) -> None:
        self.buffer += bytes(-(len(self.buffer) - _HEADER_SIZE) % size)

    def slot(self, fmt: str, align: int) -> None:
        """A numeric field (``struct`` format, little-endian), filled per message."""
        self._align(align)
        packer = struct.Struct("<" + fmt)
        self.slots.append((len(self.buffer), packer))
        self.buffer += bytes(packer.size)

    def uint32(self, value: int) -> None:
        self._align(4)
        self.buffer += struct.pack("<I", value)

    def string(self, text: str) -> None:
        data = text.encode() + b"\x00"
        self.uint32(len(data))
        self.buffer += data

    def strings(self, texts: Sequence[str]) -> None:
        self.uint32(len(texts))
        for text in texts:
            self.string(text)

    def stamp(self) -> None:
        self.slot("iI", 4)

    def header(self, frame_id: str) -> None:
        self.stamp()
        self.string(frame_id)

    def doubles(self, count: int, per_element: int = 1) -> None:
        """A sequence of ``count`` elements of ``per_element`` float64 each (float64[], Point[]).

        Its slot is empty when the sequence is: CDR aligns no empty array.
        """
        self.uint32(count)
        self.slot(f"{count * per_element}d", 8 if count else 1)

    def build(self) -> _Template:
        return _Template(bytes(self.buffer), self.slots)


class _Template:
    def __init__(self, data: bytes, slots: list[tuple[int, struct.Struct]]) -> None:
        self.data = data
        self._pack_into = [(packer.pack_into, offset) for offset, packer in slots]
        self._unpack_from = [(packer.unpack_from, offset) for offset, packer in slots]
        # The constant parts, as (start, end) byte ranges: what a message of this layout must repeat.
        bounds = [0]
        for offset, packer in slots:
            bounds += [offset, offset + packer.size]
        bounds.append(len(data))
        self._constant = [(a, b) for a, b in zip(bounds[::2], bounds[1::2], strict=True) if b > a]

    def read(self, data: bytes) -> list[tuple[float | int, ...]] | None:
        """The slots' values if ``data`` has this layout (same constants), else None.

        Bytes past the layout's end are ignored: rclpy's own messages carry a few.
        """
        if len(data) < len(self.data):
            return None
        template = self.data
        for start, end in self._constant:
            if data[start:end] != template[start:end]:
                return None
        return [unpack_from(data, offset) for unpack_from, offset in self._unpack_from]

    def fill(self, *values: Sequence[float | int]) -> bytes:
        """The message with slot k set to ``values[k]`` (a sequence of numbers)."""
        buffer = bytearray(self.data)
        for (pack_into, offset), value in zip(self._pack_into, values, strict=True):
            pack_into(buffer, offset, *value)  # type: ignore[misc]
        return bytes(buffer)


def _split(stamp_ns: int) -> tuple[int, int]:
    return stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000


class JointStateEncoder:
    """sensor_msgs/JointState with fixed names (position, velocity, effort for every joint)."""

    def __init__(self, names: Sequence[str], frame_id: str = "") -> None:
        layout = _Layout()
        layout.header(frame_id)
        layout.strings(names)
        for _ in range(3):
            layout.doubles(len(names))
        self._template = layout.build()

    def encode(self, stamp_ns: int, position: Vector, velocity: Vector, effort: Vector) -> bytes:
        return self._template.fill(_split(stamp_ns), position.tolist(), velocity.tolist(), effort.tolist())


class ClockEncoder:
    """rosgraph_msgs/Clock."""

    def __init__(self) -> None:
        layout = _Layout()
        layout.stamp()
        self._template = layout.build()

    def encode(self, stamp_ns: int) -> bytes:
        return self._template.fill(_split(stamp_ns))


class WrenchStampedEncoder:
    """geometry_msgs/WrenchStamped: a force, no torque."""

    def __init__(self, frame_id: str) -> None:
        layout = _Layout()
        layout.header(frame_id)
        layout.slot("3d", 8)
        layout.buffer += bytes(24)  # torque: zero (the force acts at the contact point)
        self._template = layout.build()

    def encode(self, stamp_ns: int, force: Vector) -> bytes:
        return self._template.fill(_split(stamp_ns), force.tolist())


@dataclass(frozen=True)
class ContactReport:
    """The numbers of one bracing_msgs/ContactState (name and frame are fixed per encoder)."""

    active: bool
    position: Vector  # (3,)
    normal: Vector  # (3,)
    normal_force: float
    friction_force: float
    slip_velocity: Vector  # (3,)
    residual: float


class ContactsEncoder:
    """bracing_msgs/Contacts with fixed contact names and frames."""

    def __init__(self, names: Sequence[str], frames: Sequence[str], frame_id: str = "world") -> None:
        layout = _Layout()
        layout.header(frame_id)
        layout.uint32(len(names))
        for name, frame in zip(names, frames, strict=True):
            layout.string(name)
            layout.string(frame)
            layout.slot("?", 1)
            layout.slot("3d3d2d3dd", 8)
        self._template = layout.build()

    def encode(self, stamp_ns: int, contacts: Sequence[ContactReport]) -> bytes:
        values: list[Sequence[float | int]] = [_split(stamp_ns)]
        for c in contacts:
            values.append((c.active,))
            values.append(
                (
                    *c.position.tolist(),
                    *c.normal.tolist(),
                    c.normal_force,
                    c.friction_force,
                    *c.slip_velocity.tolist(),
                    c.residual,
                )
            )
        return self._template.fill(*values)


class MotorStateEncoder:
    """bracing_msgs/MotorState with fixed joint names."""

    def __init__(self, names: Sequence[str]) -> None:
        layout = _Layout()
        layout.header("")
        layout.strings(names)
        for _ in range(3):
            layout.doubles(len(names))
        layout.slot("3d", 8)
        self._template = layout.build()

    def encode(
        self, stamp_ns: int, voltage: Vector, current: Vector, power: Vector, energies: tuple[float, float, float]
    ) -> bytes:
        """``energies``: (energy_consumed, energy_net, copper_loss) [J]."""
        return self._template.fill(_split(stamp_ns), voltage.tolist(), current.tolist(), power.tolist(), energies)


class MotorCommandEncoder:
    """bracing_msgs/MotorCommand with fixed joint names and mode."""

    def __init__(self, names: Sequence[str], mode: int) -> None:
        layout = _Layout()
        layout.header("")
        layout.buffer += bytes((mode,))
        layout.strings(names)
        layout.doubles(len(names))
        self._template = layout.build()

    def encode(self, stamp_ns: int, value: Vector) -> bytes:
        return self._template.fill(_split(stamp_ns), value.tolist())


class ControllerStateEncoder:
    """bracing_msgs/ControllerState with fixed contact names and command length."""

    def __init__(self, contact_names: Sequence[str], command_length: int, frame_id: str = "world") -> None:
        p = len(contact_names)
        layout = _Layout()
        layout.header(frame_id)
        layout.slot("3d3d", 8)  # hand desired, hand actual
        layout.strings(contact_names)
        layout.doubles(p)
        layout.doubles(p, per_element=3)  # brace desired: Point[]
        layout.doubles(p, per_element=3)  # brace actual
        layout.doubles(command_length)
        layout.slot("d", 8)
        self._template = layout.build()

    def encode(
        self,
        stamp_ns: int,
        hand_desired: Vector,
        hand_actual: Vector,
        desired_normal_force: Vector,
        brace_desired: Vector,
        brace_actual: Vector,
        command: Vector,
        compute_time: float,
    ) -> bytes:
        """``brace_desired``/``brace_actual``: (p, 3) arrays."""
        return self._template.fill(
            _split(stamp_ns),
            (*hand_desired.tolist(), *hand_actual.tolist()),
            desired_normal_force.tolist(),
            brace_desired.ravel().tolist(),
            brace_actual.ravel().tolist(),
            command.tolist(),
            (compute_time,),
        )


# ----------------------------------------------------------------------------- decoding


class _Reader:
    def __init__(self, data: bytes) -> None:
        if len(data) < _HEADER_SIZE or data[0] != 0 or data[1] not in (0, 1):
            raise UnsupportedEncoding(f"encapsulation {bytes(data[:2]).hex() or 'missing'} is not plain CDR")
        self.data = data
        self.endian = "<" if data[1] == 1 else ">"
        self.offset = _HEADER_SIZE

    def _take(self, fmt: str, align: int) -> tuple[object, ...]:
        self.offset += -(self.offset - _HEADER_SIZE) % align
        try:
            values = struct.unpack_from(self.endian + fmt, self.data, self.offset)
        except struct.error:
            raise DecodeError(f"message ends early (offset {self.offset} of {len(self.data)} bytes)") from None
        self.offset += struct.calcsize(fmt)
        return values

    def uint32(self) -> int:
        return int(self._take("I", 4)[0])  # type: ignore[call-overload]

    def uint8(self) -> int:
        return int(self._take("B", 1)[0])  # type: ignore[call-overload]

    def stamp_ns(self) -> int:
        sec, nanosec = self._take("iI", 4)
        return int(sec) * 1_000_000_000 + int(nanosec)  # type: ignore[call-overload]

    def string(self) -> str:
        size = self.uint32()
        start, end = self.offset, self.offset + size
        if size == 0 or end > len(self.data) or self.data[end - 1] != 0:
            raise DecodeError(f"bad string of {size} bytes at offset {start}")
        self.offset = end
        try:
            return bytes(self.data[start : end - 1]).decode()
        except UnicodeDecodeError:
            raise DecodeError(f"string at offset {start} is not UTF-8") from None

    def strings(self) -> list[str]:
        count = self._count(4)
        return [self.string() for _ in range(count)]

    def doubles(self) -> Vector:
        count = self._count(8)
        return np.array(self._take(f"{count}d", 8) if count else (), dtype=float)

    def _count(self, min_item_size: int) -> int:
        count = self.uint32()
        if count * min_item_size > len(self.data) - self.offset:
            raise DecodeError(f"sequence of {count} elements does not fit in the message")
        return count

    def header(self) -> int:
        stamp = self.stamp_ns()
        self.string()  # frame_id
        return stamp


@dataclass(frozen=True)
class JointStateData:
    stamp_ns: int
    name: list[str]
    position: Vector
    velocity: Vector
    effort: Vector


class JointStateDecoder:
    """Reads JointStates, quickly when they have the layout of ``JointStateEncoder(names)``."""

    def __init__(self, names: Sequence[str]) -> None:
        self._names = list(names)
        self._template = JointStateEncoder(names)._template

    def decode(self, data: bytes) -> JointStateData:
        values = self._template.read(data)
        if values is None:
            return decode_joint_state(data)
        (sec, nanosec), position, velocity, effort = values
        return JointStateData(
            int(sec) * 1_000_000_000 + int(nanosec),
            self._names.copy(),
            np.array(position),
            np.array(velocity),
            np.array(effort),
        )


def decode_joint_state(data: bytes) -> JointStateData:
    """A sensor_msgs/JointState from its CDR bytes."""
    reader = _Reader(data)
    stamp = reader.header()
    names = reader.strings()
    return JointStateData(stamp, names, reader.doubles(), reader.doubles(), reader.doubles())


@dataclass(frozen=True)
class MotorCommandData:
    stamp_ns: int
    mode: int
    name: list[str]
    value: Vector


class MotorCommandDecoder:
    """Reads MotorCommands, quickly when they have the layout of ``MotorCommandEncoder(names, mode)``."""

    def __init__(self, names: Sequence[str], mode: int) -> None:
        self._names, self._mode = list(names), mode
        self._template = MotorCommandEncoder(names, mode)._template

    def decode(self, data: bytes) -> MotorCommandData:
        values = self._template.read(data)
        if values is None:
            return decode_motor_command(data)
        (sec, nanosec), value = values
        return MotorCommandData(
            int(sec) * 1_000_000_000 + int(nanosec), self._mode, self._names.copy(), np.array(value)
        )


def decode_motor_command(data: bytes) -> MotorCommandData:
    """A bracing_msgs/MotorCommand from its CDR bytes."""
    reader = _Reader(data)
    stamp = reader.header()
    mode = reader.uint8()
    names = reader.strings()
    return MotorCommandData(stamp, mode, names, reader.doubles())
