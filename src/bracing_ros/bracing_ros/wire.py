"""CDR bytes of the messages a lockstep step sends and receives, without rclpy's message classes.

Why: rclpy moves every message through its generated Python class (type-checked setters,
then a conversion to C and back). For the few messages a step sends, that costs more than
the DDS write itself, and it sits on the lockstep loop's critical path. ``Publisher.publish``
accepts serialised bytes as they are, so every message here is built as bytes.

Layouts come from the message definitions (the ``.msg`` files, through the rosbags typestore
of :mod:`bracing_ros.typestore`); none is written here by hand:

- The two messages on the lockstep critical path, state out / in (``sensor_msgs/JointState``:
  the simulator encodes, the controller decodes) and command out / in
  (``bracing_msgs/MotorCommand``: the controller encodes, the simulator decodes), use a byte
  template derived from the definition (:func:`derive_template`). What is fixed for a run
  (strings, names, ``header.frame_id``, the mode, sequence lengths) is written into the
  template once; the numbers are packed per message with one ``struct`` call. A field added
  to the ``.msg`` needs no edit here: it takes its zero / empty default unless the encoder's
  spec gives it a value.
- The other messages (``Clock``, ``WrenchStamped``, ``Contacts``, ``MotorState``,
  ``ControllerState``) go through rosbags' generated serialiser
  (``Typestore.serialize_cdr`` of the typestore's message classes).
- Decoders take the template's quick path when a message has the expected layout (the
  simulator's and controller's own), else rosbags' generated deserialiser reads any valid
  message of the type (a little faster than the hand-written reader it replaced).

Median time per message [us] (``timeit``, 4 joints, 1 contact, median of 3 runs of 11
repeats on the 2-core development machine). "hand-written" is the byte template every message
had before the layouts were derived from the definitions; rclpy is ``serialize_message`` /
``deserialize_message`` with its message class:

=====================================  ============  ========  =======  =====  ========
message                                hand-written  derived   rosbags  rclpy  used
=====================================  ============  ========  =======  =====  ========
JointState encode                      1.8           1.4       6.4      9.7    derived
MotorCommand encode                    1.3           1.0       5.1      8.8    derived
JointState decode                      3.3           2.9       9.0      11.4   derived
MotorCommand decode                    2.1           2.0       7.0      10.2   derived
Clock encode                           1.0                     2.0             rosbags
WrenchStamped encode                   1.3                     4.7             rosbags
Contacts encode                        2.1                     8.8             rosbags
MotorState encode                      2.0                     8.4             rosbags
ControllerState encode                 2.7                     10.0            rosbags
=====================================  ============  ========  =======  =====  ========

A decoder reading another layout (another frame id, names in another order) costs the
template's check and rosbags: 9.7 us a JointState, 7.4 a MotorCommand (the hand-written
reader: 10.5, 8.0). rosbags costs at most ~7 us a message more than a template for the
five reports (+18 us a step for the simulator's four, +7 us for the controller's one), under
the ~15 us a message past which a derived template would be used for them too; and they go
out after the step's JointState / MotorCommand, not before it.

The bytes are what rclpy itself produces: plain CDR (XCDR1) with the little-endian
encapsulation header, alignment relative to the end of that header. The tests check every
encoder and decoder against ``rclpy.serialization``. Encapsulations other than plain CDR
raise :class:`UnsupportedEncoding`, so the caller can fall back to rclpy.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from operator import itemgetter
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.interfaces import Nodetype

from bracing_core.types import Vector
from bracing_ros.typestore import bracing_typestore

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

_FieldDesc = Any  # rosbags' FieldDesc, (Nodetype, argument) tuples nested; a union mypy cannot narrow by kind

_HEADER_SIZE = 4  # encapsulation header; CDR alignment counts from its end
_ENCAPSULATION_LE = b"\x00\x01\x00\x00"

JOINT_STATE = "sensor_msgs/msg/JointState"
MOTOR_COMMAND = "bracing_msgs/msg/MotorCommand"

_NUMBERS = {  # ROS 2 base type -> struct format character (its size is its CDR alignment)
    "bool": "?",
    "byte": "B",
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


class DecodeError(ValueError):
    """Bytes that are not a valid message of the expected type."""


class UnsupportedEncoding(DecodeError):
    """Valid-looking data in an encapsulation these decoders do not read (not plain CDR)."""


# ----------------------------------------------------------------------------- templates


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
    builder = _Builder(typestore if typestore is not None else bracing_typestore())
    builder.fields(typename, spec)
    return builder.build()


@dataclass
class _Slot:
    start: int  # offset of its first number (after the alignment before it)
    tokens: list[str]  # struct format items: numbers, and padding between them
    count: int = 0  # numbers


class _Builder:
    """Walks a definition the way rosbags' CDR generator does, writing the template's bytes."""

    def __init__(self, store: Typestore) -> None:
        self.store = store
        self.buffer = bytearray(_ENCAPSULATION_LE)
        self.slots: list[_Slot] = []
        self._live: _Slot | None = None  # the slot being written

    # -- bytes

    def _pad(self, align: int) -> int:
        size = -(len(self.buffer) - _HEADER_SIZE) % align
        self.buffer += bytes(size)
        return size

    def _constant(self, char: str, value: object) -> None:
        packer = struct.Struct("<" + char)
        self._pad(packer.size)
        self.buffer += packer.pack(value)

    def _string(self, text: object, where: str) -> None:
        if not isinstance(text, str):
            raise TypeError(f"{where}: a string field needs a str, not {text!r}")
        data = text.encode() + b"\x00"
        self._constant("I", len(data))
        self.buffer += data

    def _numbers(self, char: str, count: int) -> None:
        """``count`` numbers of the slot being written."""
        slot = self._live
        assert slot is not None
        if count == 0:
            return  # CDR aligns no empty array
        size = struct.calcsize(char)
        if not slot.tokens:  # the slot starts here, after the alignment (part of the constant before it)
            self._pad(size)
            slot.start = len(self.buffer)
        elif pad := self._pad(size):
            slot.tokens.append(f"{pad}x")
        slot.tokens.append(f"{count}{char}")
        slot.count += count
        self.buffer += bytes(size * count)

    # -- the walk

    def fields(self, typename: str, spec: Mapping[str, Any]) -> None:
        if not isinstance(spec, Mapping):
            raise TypeError(f"{typename}: a nested message needs a mapping of its fields, not {spec!r}")
        _, fields = self.store.fielddefs[typename]
        unknown = set(spec) - {name for name, _ in fields}
        if unknown:
            raise ValueError(f"{typename} has no field {', '.join(sorted(unknown))}")
        for name, desc in fields:
            self.field(desc, spec.get(name, _DEFAULT), f"{typename}.{name}")

    def field(self, desc: _FieldDesc, value: Any, where: str) -> None:
        """One field: constant ``value`` (or its default), or a slot for a :class:`PerMessage`."""
        kind, arg = desc
        if isinstance(value, PerMessage):
            self._slot(desc, value, where)
        elif kind == Nodetype.BASE:
            base, bound = arg
            if base == "string":
                text = "" if value is _DEFAULT else value
                if bound and isinstance(text, str) and len(text) > bound:
                    raise ValueError(f"{where}: a string of at most {bound} characters, not {len(text)}")
                self._string(text, where)
            else:
                self._constant(_char(base, where), 0 if value is _DEFAULT else value)
        elif kind == Nodetype.NAME:
            self.fields(arg, {} if value is _DEFAULT else value)
        else:
            sub, bound = arg
            if value is _DEFAULT:
                elements = [_DEFAULT] * bound if kind == Nodetype.ARRAY else []
            else:
                elements = list(value)
            if kind == Nodetype.ARRAY and len(elements) != bound:
                raise ValueError(f"{where}: an array of {bound}, not {len(elements)}")
            if kind == Nodetype.SEQUENCE:
                if bound and len(elements) > bound:
                    raise ValueError(f"{where}: at most {bound} elements, not {len(elements)}")
                self._constant("I", len(elements))
            for element in elements:
                self.field(sub, element, where)

    def _slot(self, desc: _FieldDesc, marker: PerMessage, where: str) -> None:
        kind, arg = desc
        count = 1
        if kind == Nodetype.SEQUENCE:
            if marker.count is None:
                raise ValueError(f"{where}: a sequence filled per message needs its length (PerMessage(count))")
            sub, bound = arg
            if bound and marker.count > bound:
                raise ValueError(f"{where}: at most {bound} elements, not {marker.count}")
            self._constant("I", marker.count)
            desc, count = sub, marker.count
        elif marker.count is not None:
            raise ValueError(f"{where}: only a sequence takes a length")
        self._live = _Slot(len(self.buffer), [])
        self.slots.append(self._live)
        if desc[0] == Nodetype.BASE:
            self._numbers(_char(desc[1][0], where, per_message=True), count)
        else:
            for _ in range(count):
                self._numbers_of(desc, where)
        self._live = None

    def _numbers_of(self, desc: _FieldDesc, where: str) -> None:
        kind, arg = desc
        if kind == Nodetype.BASE:
            self._numbers(_char(arg[0], where, per_message=True), 1)
        elif kind == Nodetype.NAME:
            for name, sub in self.store.fielddefs[arg][1]:
                self._numbers_of(sub, f"{where}.{name}")
        elif kind == Nodetype.ARRAY:
            sub, length = arg
            if sub[0] == Nodetype.BASE:
                self._numbers(_char(sub[1][0], where, per_message=True), length)
            else:
                for _ in range(length):
                    self._numbers_of(sub, where)
        else:
            raise ValueError(f"{where}: a sequence inside a per-message part (its length would vary)")

    def build(self) -> Template:
        chunks, formats, end = [], [], 0
        for slot in self.slots:
            chunks.append(bytes(self.buffer[end : slot.start]))
            formats.append("".join(slot.tokens))
            end = slot.start + struct.calcsize("<" + formats[-1])
        chunks.append(bytes(self.buffer[end:]))
        return Template(chunks, formats, [slot.count for slot in self.slots])


def _char(base: str, where: str, per_message: bool = False) -> str:
    if base == "string" and per_message:
        raise ValueError(f"{where}: a string in a per-message part (its length would vary)")
    try:
        return _NUMBERS[base]
    except KeyError:
        raise ValueError(f"{where}: type {base} is not supported") from None


# ----------------------------------------------------------------------------- encoding


class JointStateEncoder:
    """sensor_msgs/JointState with fixed names (position, velocity, effort for every joint)."""

    def __init__(self, names: Sequence[str], frame_id: str = "") -> None:
        self._template = derive_template(JOINT_STATE, _joint_state_spec(names, frame_id))

    def encode(self, stamp_ns: int, position: Vector, velocity: Vector, effort: Vector) -> bytes:
        return self._template.fill(
            divmod(stamp_ns, 1_000_000_000), position.tolist(), velocity.tolist(), effort.tolist()
        )


def _joint_state_spec(names: Sequence[str], frame_id: str) -> dict[str, Any]:
    n = len(names)
    return {
        "header": {"stamp": PER_MESSAGE, "frame_id": frame_id},
        "name": list(names),
        "position": PerMessage(n),
        "velocity": PerMessage(n),
        "effort": PerMessage(n),
    }


class MotorCommandEncoder:
    """bracing_msgs/MotorCommand with fixed joint names and mode."""

    def __init__(self, names: Sequence[str], mode: int) -> None:
        self._template = derive_template(MOTOR_COMMAND, _motor_command_spec(names, mode))

    def encode(self, stamp_ns: int, value: Vector) -> bytes:
        return self._template.fill(divmod(stamp_ns, 1_000_000_000), value.tolist())


def _motor_command_spec(names: Sequence[str], mode: int) -> dict[str, Any]:
    return {
        "header": {"stamp": PER_MESSAGE, "frame_id": ""},
        "mode": mode,
        "name": list(names),
        "value": PerMessage(len(names)),
    }


class _Messages:
    """Message objects of one type of the typestore; fields not given are zero / empty.

    The defaults are shared between messages: the objects are for serialising, not editing.
    """

    def __init__(self, store: Typestore, typename: str) -> None:
        msgdef = store.get_msgdef(typename)  # also generates its serialiser now, not at the first message
        self._cls = msgdef.cls
        self._defaults = {name: _default_value(store, desc) for name, desc in msgdef.fields}

    def __call__(self, **values: object) -> Any:
        return self._cls(**(self._defaults | values))


def _default_value(store: Typestore, desc: _FieldDesc) -> object:
    kind, arg = desc
    if kind == Nodetype.BASE:
        base = arg[0]
        return "" if base == "string" else False if base == "bool" else 0.0 if base.startswith("float") else 0
    if kind == Nodetype.NAME:
        return _Messages(store, arg)()
    sub, length = arg
    if kind == Nodetype.SEQUENCE:
        length = 0
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        return np.zeros(length, dtype={"bool": np.bool_, "char": np.uint8, "byte": np.uint8}.get(sub[1][0], sub[1][0]))
    return [_default_value(store, sub) for _ in range(length)]


def _float64s(values: Vector) -> Vector:
    """What rosbags serialises a float64[] from: contiguous float64 (the same array if it is)."""
    return np.ascontiguousarray(values, dtype=np.float64)


class _Serializer:
    """The typestore's message classes and generated CDR serialiser for a few types."""

    def __init__(self) -> None:
        self.store = bracing_typestore()
        types = self.store.types
        self.Time = types["builtin_interfaces/msg/Time"]
        self.Header = types["std_msgs/msg/Header"]
        self.Point = types["geometry_msgs/msg/Point"]
        self.Vector3 = types["geometry_msgs/msg/Vector3"]

    def time(self, stamp_ns: int) -> Any:
        return self.Time(*divmod(stamp_ns, 1_000_000_000))

    def header(self, stamp_ns: int, frame_id: str) -> Any:
        return self.Header(self.time(stamp_ns), frame_id)

    def serialize(self, message: object, typename: str) -> bytes:
        return bytes(self.store.serialize_cdr(message, typename, little_endian=True))


class ClockEncoder:
    """rosgraph_msgs/Clock."""

    def __init__(self) -> None:
        self._ser = _Serializer()
        self._clock = _Messages(self._ser.store, "rosgraph_msgs/msg/Clock")

    def encode(self, stamp_ns: int) -> bytes:
        message = self._clock(clock=self._ser.time(stamp_ns))
        return self._ser.serialize(message, "rosgraph_msgs/msg/Clock")


class WrenchStampedEncoder:
    """geometry_msgs/WrenchStamped: a force, no torque."""

    def __init__(self, frame_id: str) -> None:
        self._ser, self._frame_id = _Serializer(), frame_id
        self._wrench_stamped = _Messages(self._ser.store, "geometry_msgs/msg/WrenchStamped")
        self._wrench = _Messages(self._ser.store, "geometry_msgs/msg/Wrench")

    def encode(self, stamp_ns: int, force: Vector) -> bytes:
        ser = self._ser
        message = self._wrench_stamped(
            header=ser.header(stamp_ns, self._frame_id),
            wrench=self._wrench(force=ser.Vector3(*force.tolist())),  # torque: zero (force at the contact point)
        )
        return ser.serialize(message, "geometry_msgs/msg/WrenchStamped")


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
        self._ser, self._frame_id = _Serializer(), frame_id
        self._names = list(zip(names, frames, strict=True))
        self._contacts = _Messages(self._ser.store, "bracing_msgs/msg/Contacts")
        self._contact = _Messages(self._ser.store, "bracing_msgs/msg/ContactState")

    def encode(self, stamp_ns: int, contacts: Sequence[ContactReport]) -> bytes:
        ser = self._ser
        states = [
            self._contact(
                name=name,
                frame=frame,
                active=bool(c.active),
                position=ser.Point(*c.position.tolist()),
                normal=ser.Vector3(*c.normal.tolist()),
                normal_force=float(c.normal_force),
                friction_force=float(c.friction_force),
                slip_velocity=ser.Vector3(*c.slip_velocity.tolist()),
                residual=float(c.residual),
            )
            for (name, frame), c in zip(self._names, contacts, strict=True)
        ]
        message = self._contacts(header=ser.header(stamp_ns, self._frame_id), contacts=states)
        return ser.serialize(message, "bracing_msgs/msg/Contacts")


class MotorStateEncoder:
    """bracing_msgs/MotorState with fixed joint names."""

    def __init__(self, names: Sequence[str]) -> None:
        self._ser, self._names = _Serializer(), list(names)
        self._motor_state = _Messages(self._ser.store, "bracing_msgs/msg/MotorState")

    def encode(
        self,
        stamp_ns: int,
        voltage: Vector,
        current: Vector,
        power: Vector,
        energies: tuple[float, float, float],
        temperature: Vector,
    ) -> bytes:
        """``energies``: (energy_consumed, energy_net, copper_loss) [J]; ``temperature``: the windings' T
        [degC], empty where the thermal model does not apply."""
        energy_consumed, energy_net, copper_loss = energies
        message = self._motor_state(
            header=self._ser.header(stamp_ns, ""),
            name=self._names,
            voltage=_float64s(voltage),
            current=_float64s(current),
            power=_float64s(power),
            energy_consumed=float(energy_consumed),
            energy_net=float(energy_net),
            copper_loss=float(copper_loss),
            temperature=_float64s(temperature),
        )
        return self._ser.serialize(message, "bracing_msgs/msg/MotorState")


class ControllerStateEncoder:
    """bracing_msgs/ControllerState with fixed contact names.

    ``command_length`` is the length of the commands encoded (kept for callers; the
    serialiser takes any).
    """

    def __init__(self, contact_names: Sequence[str], command_length: int, frame_id: str = "world") -> None:
        self._ser, self._frame_id = _Serializer(), frame_id
        self._contact_names, self.command_length = list(contact_names), command_length
        self._controller_state = _Messages(self._ser.store, "bracing_msgs/msg/ControllerState")

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
        Point = self._ser.Point
        message = self._controller_state(
            header=self._ser.header(stamp_ns, self._frame_id),
            hand_desired=Point(*hand_desired.tolist()),
            hand_actual=Point(*hand_actual.tolist()),
            contact_name=self._contact_names,
            desired_normal_force=_float64s(desired_normal_force),
            brace_desired=[Point(*p) for p in brace_desired.tolist()],
            brace_actual=[Point(*p) for p in brace_actual.tolist()],
            command=_float64s(command),
            compute_time=float(compute_time),
        )
        return self._ser.serialize(message, "bracing_msgs/msg/ControllerState")


# ----------------------------------------------------------------------------- decoding


def _deserialize(data: bytes, typename: str) -> Any:
    """Any valid message of ``typename`` (rosbags' generated deserialiser).

    Bytes past the message's end are ignored: rclpy's own messages can carry several
    (``Typestore.deserialize_cdr`` refuses more than 3, so its generated function is called).
    """
    if len(data) < _HEADER_SIZE or data[0] != 0 or data[1] not in (0, 1):
        raise UnsupportedEncoding(f"encapsulation {bytes(data[:2]).hex() or 'missing'} is not plain CDR")
    store = bracing_typestore()
    msgdef = store.get_msgdef(typename)
    read = msgdef.deserialize_cdr_le if data[1] == 1 else msgdef.deserialize_cdr_be
    try:
        return read(data[_HEADER_SIZE:], 0, msgdef.cls, store)[0]
    except Exception as exc:  # SerdeError, struct.error, ValueError: whatever arbitrary bytes provoke
        raise DecodeError(f"not a {typename}: {exc}") from None


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces/Time (rosbags' or rclpy's) in nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


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
        self._template = derive_template(JOINT_STATE, _joint_state_spec(names, ""))
        bracing_typestore().get_msgdef(JOINT_STATE)  # the general reader's code, generated now

    def decode(self, data: bytes) -> JointStateData:
        values = self._template.read(data)
        if values is None:
            return decode_joint_state(data)
        (sec, nanosec), position, velocity, effort = values
        return JointStateData(
            sec * 1_000_000_000 + nanosec,
            self._names.copy(),
            np.array(position),
            np.array(velocity),
            np.array(effort),
        )


def decode_joint_state(data: bytes) -> JointStateData:
    """A sensor_msgs/JointState from its CDR bytes."""
    return joint_state_data(_deserialize(data, JOINT_STATE))


def joint_state_data(msg: Any) -> JointStateData:
    """The numbers of a JointState message object (rosbags' or rclpy's)."""
    return JointStateData(
        stamp_ns(msg.header.stamp),
        list(msg.name),
        np.array(msg.position, dtype=float),
        np.array(msg.velocity, dtype=float),
        np.array(msg.effort, dtype=float),
    )


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
        self._template = derive_template(MOTOR_COMMAND, _motor_command_spec(names, mode))
        bracing_typestore().get_msgdef(MOTOR_COMMAND)

    def decode(self, data: bytes) -> MotorCommandData:
        values = self._template.read(data)
        if values is None:
            return decode_motor_command(data)
        (sec, nanosec), value = values
        return MotorCommandData(sec * 1_000_000_000 + nanosec, self._mode, self._names.copy(), np.array(value))


def decode_motor_command(data: bytes) -> MotorCommandData:
    """A bracing_msgs/MotorCommand from its CDR bytes."""
    return motor_command_data(_deserialize(data, MOTOR_COMMAND))


def motor_command_data(msg: Any) -> MotorCommandData:
    """The numbers of a MotorCommand message object (rosbags' or rclpy's)."""
    return MotorCommandData(stamp_ns(msg.header.stamp), int(msg.mode), list(msg.name), np.array(msg.value, dtype=float))
