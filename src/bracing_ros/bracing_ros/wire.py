"""CDR bytes of the messages a lockstep step sends and receives, without rclpy's message classes.

Why: rclpy moves every message through its generated Python class (type-checked setters,
then a conversion to C and back). For the few messages a step sends, that costs more than
the DDS write itself, and it sits on the lockstep loop's critical path. ``Publisher.publish``
accepts serialised bytes as they are, so every message here is built as bytes.

Layouts come from the message definitions (the ``.msg`` files, through the rosbags typestore
of :mod:`bracing_core.typestore`, walked by :mod:`bracing_core.cdr`); none is written here by hand:

- The two messages on the lockstep critical path, state out / in (``sensor_msgs/JointState``:
  the simulator encodes, the controller decodes) and command out / in
  (``bracing_msgs/MotorCommand``: the controller encodes, the simulator decodes), and the
  controller's other message on every state (``ControllerState``), use a byte
  template derived from the definition (:func:`derive_template`). What is fixed for a run
  (strings, names, ``header.frame_id``, the mode, sequence lengths) is written into the
  template once; the numbers are packed per message with one ``struct`` call. A field added
  to the ``.msg`` needs no edit here: it takes its zero / empty default unless the encoder's
  spec gives it a value.
- The other messages (``Clock``, ``WrenchStamped``, ``Contacts``, ``MotorState``) go through
  rosbags' generated serialiser (``Typestore.serialize_cdr`` of the typestore's message classes).
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
ControllerState encode                 2.7           2.1       10.0            derived
=====================================  ============  ========  =======  =====  ========

A decoder reading another layout (another frame id, names in another order) costs the
template's check and rosbags: 9.7 us a JointState, 7.4 a MotorCommand (the hand-written
reader: 10.5, 8.0). rosbags costs at most ~7 us a message more than a template for the
simulator's four reports (+18 us a step), under the ~15 us a message past which a derived
template would be used for them too; and they go out after the step's JointState, not before
it. The controller's ControllerState took a template: its ~8 us saved on every
state leave the controller's callback as short as it can be (make bench's callback p50).

The bytes are what rclpy itself produces: plain CDR (XCDR1) with the little-endian
encapsulation header, alignment relative to the end of that header. The tests check every
encoder and decoder against ``rclpy.serialization``. Encapsulations other than plain CDR
raise :class:`UnsupportedEncoding`, so the caller can fall back to rclpy.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from operator import itemgetter
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.interfaces import Nodetype

from bracing_core import cdr
from bracing_core.cdr import FieldDesc
from bracing_core.message_limits import MessageLimits, check_cdr_sizes
from bracing_core.types import Vector
from bracing_core.typestore import (
    CLOCK,
    CONTACT_STATE,
    CONTACTS,
    CONTROLLER_STATE,
    JOINT_STATE,
    MOTOR_COMMAND,
    MOTOR_STATE,
    ODOMETRY,
    RECORD_BATCH,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
    bracing_typestore,
)

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


class DecodeError(ValueError):
    """Bytes that are not a valid message of the expected type."""

    kind = "malformed"  # the kind of refusal a node's rate-limited log reports it under (as SizeError's)


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


def _default_value(store: Typestore, desc: FieldDesc) -> object:
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
        return np.zeros(length, dtype=cdr.STRUCT_CODES.get(sub[1][0], sub[1][0]))
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
        self._clock = _Messages(self._ser.store, CLOCK)

    def encode(self, stamp_ns: int) -> bytes:
        message = self._clock(clock=self._ser.time(stamp_ns))
        return self._ser.serialize(message, CLOCK)


class RecordBatchEncoder:
    """bracing_msgs/RecordBatch (``bracing_ros.record_batch``): 16 us for ~100 kB (100 states of the paper
    arm), where rclpy's message class took 560 us (it converts the uint8[] byte by byte)."""

    def __init__(self, node: str) -> None:
        self._ser = _Serializer()
        self._batch = _Messages(self._ser.store, RECORD_BATCH)
        self._node = node

    def encode(self, sequence: int, topics: list[str], topic_of: list[int], end: list[int], data: bytes) -> bytes:
        message = self._batch(
            node=self._node,
            sequence=sequence,
            topics=topics,
            topic_of=np.array(topic_of, dtype=np.uint16),
            end=np.array(end, dtype=np.uint32),
            data=np.frombuffer(data, dtype=np.uint8),
        )
        return self._ser.serialize(message, RECORD_BATCH)


class WrenchStampedEncoder:
    """geometry_msgs/WrenchStamped: a force, no torque."""

    def __init__(self, frame_id: str) -> None:
        self._ser, self._frame_id = _Serializer(), frame_id
        self._wrench_stamped = _Messages(self._ser.store, WRENCH_STAMPED)
        self._wrench = _Messages(self._ser.store, "geometry_msgs/msg/Wrench")

    def encode(self, stamp_ns: int, force: Vector) -> bytes:
        ser = self._ser
        message = self._wrench_stamped(
            header=ser.header(stamp_ns, self._frame_id),
            wrench=self._wrench(force=ser.Vector3(*force.tolist())),  # torque: zero (force at the contact point)
        )
        return ser.serialize(message, WRENCH_STAMPED)


class Vector3StampedEncoder:
    """geometry_msgs/Vector3Stamped in one frame (a byte template: only the stamp and the vector per message)."""

    def __init__(self, frame_id: str) -> None:
        spec = {"header": {"stamp": PER_MESSAGE, "frame_id": frame_id}, "vector": PER_MESSAGE}
        self._template = derive_template(VECTOR3_STAMPED, spec)

    def encode(self, stamp_ns: int, vector: Vector) -> bytes:
        return self._template.fill(divmod(stamp_ns, 1_000_000_000), vector.tolist())


class OdometryEncoder:
    """nav_msgs/Odometry of a base in the plane (a byte template: the stamp, the pose and the twist per message;
    the frames fixed, the covariances zero)."""

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        spec = {
            "header": {"stamp": PER_MESSAGE, "frame_id": frame_id},
            "child_frame_id": child_frame_id,
            "pose": {"pose": {"position": PER_MESSAGE, "orientation": PER_MESSAGE}},
            "twist": {"twist": {"linear": PER_MESSAGE, "angular": PER_MESSAGE}},
        }
        self._template = derive_template(ODOMETRY, spec)

    def encode(
        self,
        stamp_ns: int,
        xy: tuple[float, float],
        quaternion: tuple[float, float, float, float],
        linear_xy: tuple[float, float],
        yaw_rate: float,
    ) -> bytes:
        """Pose (x, y [m], heading as quaternion x, y, z, w) and twist (linear x, y [m/s] in the child frame,
        angular z [rad/s])."""
        return self._template.fill(
            divmod(stamp_ns, 1_000_000_000), (*xy, 0.0), quaternion, (*linear_xy, 0.0), (0.0, 0.0, yaw_rate)
        )


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
        self._contacts = _Messages(self._ser.store, CONTACTS)
        self._contact = _Messages(self._ser.store, CONTACT_STATE)

    def encode(
        self, stamp_ns: int, contacts: Sequence[ContactReport], names: Sequence[tuple[str, str]] | None = None
    ) -> bytes:
        """``names``: (name, frame) of each contact in this message instead of the fixed ones."""
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
            for (name, frame), c in zip(self._names if names is None else names, contacts, strict=True)
        ]
        message = self._contacts(header=ser.header(stamp_ns, self._frame_id), contacts=states)
        return ser.serialize(message, CONTACTS)


class MotorStateEncoder:
    """bracing_msgs/MotorState with fixed joint names."""

    def __init__(self, names: Sequence[str]) -> None:
        self._ser, self._names = _Serializer(), list(names)
        self._motor_state = _Messages(self._ser.store, MOTOR_STATE)

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
        return self._ser.serialize(message, MOTOR_STATE)


class ControllerStateEncoder:
    """bracing_msgs/ControllerState with fixed contact names and ``command_length`` (a byte template:
    2.1 us a message against rosbags' 10, on every state the controller answers)."""

    def __init__(self, contact_names: Sequence[str], command_length: int, frame_id: str = "world") -> None:
        spec = _controller_state_spec(contact_names, command_length, frame_id)
        self._template = derive_template(CONTROLLER_STATE, spec)

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
            divmod(stamp_ns, 1_000_000_000),
            hand_desired.tolist(),
            hand_actual.tolist(),
            desired_normal_force.tolist(),
            brace_desired.ravel().tolist(),
            brace_actual.ravel().tolist(),
            command.tolist(),
            (float(compute_time),),
        )


def _controller_state_spec(contact_names: Sequence[str], command_length: int, frame_id: str) -> dict[str, Any]:
    p = len(contact_names)
    return {
        "header": {"stamp": PER_MESSAGE, "frame_id": frame_id},
        "hand_desired": PER_MESSAGE,
        "hand_actual": PER_MESSAGE,
        "contact_name": list(contact_names),
        "desired_normal_force": PerMessage(p),
        "brace_desired": PerMessage(p),
        "brace_actual": PerMessage(p),
        "command": PerMessage(command_length),
        "compute_time": PER_MESSAGE,
    }


# ----------------------------------------------------------------------------- decoding


def _deserialize(data: bytes, typename: str) -> Any:
    """Any valid message of ``typename`` (rosbags' generated deserialiser).

    Bytes past the message's end are ignored: rclpy's own messages can carry several
    (``Typestore.deserialize_cdr`` refuses more than 3, so its generated function is called).
    """
    if len(data) < cdr.HEADER_SIZE or data[0] != 0 or data[1] not in (0, 1):
        raise UnsupportedEncoding(f"encapsulation {bytes(data[:2]).hex() or 'missing'} is not plain CDR")
    store = bracing_typestore()
    msgdef = store.get_msgdef(typename)
    read = msgdef.deserialize_cdr_le if data[1] == 1 else msgdef.deserialize_cdr_be
    try:
        return read(data[cdr.HEADER_SIZE :], 0, msgdef.cls, store)[0]
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
    """Reads JointStates, quickly when they have the layout of ``JointStateEncoder(names)``. Another
    layout is checked against ``limits`` from its length fields first (``SizeError``), if given."""

    def __init__(self, names: Sequence[str], limits: MessageLimits | None = None) -> None:
        self._names, self._limits = list(names), limits
        self._template = derive_template(JOINT_STATE, _joint_state_spec(names, ""))
        bracing_typestore().get_msgdef(JOINT_STATE)  # the general reader's code, generated now

    def decode(self, data: bytes) -> JointStateData:
        values = self._template.read(data)
        if values is None:
            if self._limits is not None:
                check_cdr_sizes(bracing_typestore(), JOINT_STATE, data, self._limits)
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
    """Reads MotorCommands, quickly when they have the layout of ``MotorCommandEncoder(names, mode)``;
    another layout is checked against ``limits`` first, as ``JointStateDecoder``'s."""

    def __init__(self, names: Sequence[str], mode: int, limits: MessageLimits | None = None) -> None:
        self._names, self._mode, self._limits = list(names), mode, limits
        self._template = derive_template(MOTOR_COMMAND, _motor_command_spec(names, mode))
        bracing_typestore().get_msgdef(MOTOR_COMMAND)

    def decode(self, data: bytes) -> MotorCommandData:
        values = self._template.read(data)
        if values is None:
            if self._limits is not None:
                check_cdr_sizes(bracing_typestore(), MOTOR_COMMAND, data, self._limits)
            return decode_motor_command(data)
        (sec, nanosec), value = values
        return MotorCommandData(sec * 1_000_000_000 + nanosec, self._mode, self._names.copy(), np.array(value))


def decode_motor_command(data: bytes) -> MotorCommandData:
    """A bracing_msgs/MotorCommand from its CDR bytes."""
    return motor_command_data(_deserialize(data, MOTOR_COMMAND))


def motor_command_data(msg: Any) -> MotorCommandData:
    """The numbers of a MotorCommand message object (rosbags' or rclpy's)."""
    return MotorCommandData(stamp_ns(msg.header.stamp), int(msg.mode), list(msg.name), np.array(msg.value, dtype=float))


def decode_checked(data: bytes, typename: str, limits: MessageLimits) -> Any:
    """Any valid message of ``typename`` from its CDR bytes (rosbags' message object), checked against
    ``limits`` from its length fields before its elements are decoded (``SizeError``)."""
    check_cdr_sizes(bracing_typestore(), typename, data, limits)
    return _deserialize(data, typename)
