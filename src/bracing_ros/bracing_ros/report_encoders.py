"""CDR bytes of the simulator's per-state reports (``Clock``, ``WrenchStamped``, ``Contacts``,
``MotorState``) and of the record batch, through rosbags' generated serialiser
(``Typestore.serialize_cdr`` of the typestore's message classes): each costs a few microseconds more
than a byte template would (see :mod:`bracing_ros.wire`'s table), and they go out after the step's
JointState, not before it. The bytes are rclpy's (test_wire checks them against
``rclpy.serialization``).

The three step reports' encoders also give their byte templates (``template``: derived from the
definitions, :func:`bracing_ros.cdr_template.derive_template`), which the simulator's C++ path on rcl
fills (``bracing_rcl.ReportPath``): the same bytes, the names, frames and lengths fixed per run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.interfaces import Nodetype

from bracing_core import cdr
from bracing_core.cdr import FieldDesc
from bracing_core.stamps import sec_nanosec
from bracing_core.types import Vector
from bracing_core.typestore import (
    CLOCK,
    CONTACT_STATE,
    CONTACTS,
    MOTOR_STATE,
    RECORD_BATCH,
    WRENCH_STAMPED,
    bracing_typestore,
)
from bracing_ros.cdr_template import PER_MESSAGE, PerMessage, Template, derive_template

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


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
        return self.Time(*sec_nanosec(stamp_ns))

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

    def template(self) -> Template:
        """The byte template: the stamp, then the force (3); the torque zero."""
        spec = {"header": {"stamp": PER_MESSAGE, "frame_id": self._frame_id}, "wrench": {"force": PER_MESSAGE}}
        return derive_template(WRENCH_STAMPED, spec)

    def encode(self, stamp_ns: int, force: Vector) -> bytes:
        ser = self._ser
        message = self._wrench_stamped(
            header=ser.header(stamp_ns, self._frame_id),
            wrench=self._wrench(force=ser.Vector3(*force.tolist())),  # torque: zero (force at the contact point)
        )
        return ser.serialize(message, WRENCH_STAMPED)


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

    def template(self) -> Template:
        """The byte template of the fixed contacts: the stamp, then per contact its numbers in ContactState's
        order (active, position, normal, normal_force, friction_force, slip_velocity, residual)."""
        numbers = ("active", "position", "normal", "normal_force", "friction_force", "slip_velocity", "residual")
        states = [{"name": name, "frame": frame} | dict.fromkeys(numbers, PER_MESSAGE) for name, frame in self._names]
        header = {"stamp": PER_MESSAGE, "frame_id": self._frame_id}
        return derive_template(CONTACTS, {"header": header, "contacts": states})

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

    def template(self, temperatures: int) -> Template:
        """The byte template with ``temperatures`` windings' temperatures (0 without the thermal model): the stamp,
        then voltage, current, power (each per joint), temperature, and the three energies."""
        per_joint = PerMessage(len(self._names))
        spec = {
            "header": {"stamp": PER_MESSAGE},
            "name": self._names,
            **dict.fromkeys(("voltage", "current", "power"), per_joint),
            "temperature": PerMessage(temperatures),
            **dict.fromkeys(("energy_consumed", "energy_net", "copper_loss"), PER_MESSAGE),
        }
        return derive_template(MOTOR_STATE, spec)

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
