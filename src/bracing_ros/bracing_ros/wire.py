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
  template derived from the definition (:func:`bracing_ros.cdr_template.derive_template`). What is fixed for a run
  (strings, names, ``header.frame_id``, the mode, sequence lengths) is written into the
  template once; the numbers are packed per message with one ``struct`` call. A field added
  to the ``.msg`` needs no edit here: it takes its zero / empty default unless the encoder's
  spec gives it a value.
- The other messages (``Clock``, ``WrenchStamped``, ``Contacts``, ``MotorState``) go through
  rosbags' generated serialiser (``Typestore.serialize_cdr`` of the typestore's message classes),
  in :mod:`bracing_ros.report_encoders`, on the simulator's Python path; its C++ path on rcl fills
  derived templates of them (``bracing_rcl.StatePath``, ``ReportPath``).
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

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bracing_core import cdr
from bracing_core.message_limits import MessageLimits, check_cdr_sizes
from bracing_core.stamps import ns_of, sec_nanosec, stamp_ns
from bracing_core.types import Vector
from bracing_core.typestore import (
    CONTROLLER_STATE,
    JOINT_STATE,
    MOTOR_COMMAND,
    ODOMETRY,
    VECTOR3_STAMPED,
    bracing_typestore,
)
from bracing_ros.cdr_template import PER_MESSAGE, PerMessage, Template, derive_template


class DecodeError(ValueError):
    """Bytes that are not a valid message of the expected type."""

    kind = "malformed"  # the kind of refusal a node's rate-limited log reports it under (as SizeError's)


class UnsupportedEncoding(DecodeError):
    """Valid-looking data in an encapsulation these decoders do not read (not plain CDR)."""


# ----------------------------------------------------------------------------- encoding


class JointStateEncoder:
    """sensor_msgs/JointState with fixed names (position, velocity, effort for every joint)."""

    def __init__(self, names: Sequence[str], frame_id: str = "") -> None:
        self._template = derive_template(JOINT_STATE, _joint_state_spec(names, frame_id))

    @property
    def template(self) -> Template:
        return self._template

    def encode(self, stamp_ns: int, position: Vector, velocity: Vector, effort: Vector) -> bytes:
        return self._template.fill(sec_nanosec(stamp_ns), position.tolist(), velocity.tolist(), effort.tolist())


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

    @property
    def template(self) -> Template:
        return self._template

    def encode(self, stamp_ns: int, value: Vector) -> bytes:
        return self._template.fill(sec_nanosec(stamp_ns), value.tolist())


def _motor_command_spec(names: Sequence[str], mode: int) -> dict[str, Any]:
    return {
        "header": {"stamp": PER_MESSAGE, "frame_id": ""},
        "mode": mode,
        "name": list(names),
        "value": PerMessage(len(names)),
    }


class Vector3StampedEncoder:
    """geometry_msgs/Vector3Stamped in one frame (a byte template: only the stamp and the vector per message)."""

    def __init__(self, frame_id: str) -> None:
        spec = {"header": {"stamp": PER_MESSAGE, "frame_id": frame_id}, "vector": PER_MESSAGE}
        self._template = derive_template(VECTOR3_STAMPED, spec)

    def encode(self, stamp_ns: int, vector: Vector) -> bytes:
        return self._template.fill(sec_nanosec(stamp_ns), vector.tolist())


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
            sec_nanosec(stamp_ns), (*xy, 0.0), quaternion, (*linear_xy, 0.0), (0.0, 0.0, yaw_rate)
        )


class ControllerStateEncoder:
    """bracing_msgs/ControllerState with fixed contact names and ``command_length`` (a byte template:
    2.1 us a message against rosbags' 10, on every state the controller answers)."""

    def __init__(self, contact_names: Sequence[str], command_length: int, frame_id: str = "world") -> None:
        spec = _controller_state_spec(contact_names, command_length, frame_id)
        self._template = derive_template(CONTROLLER_STATE, spec)

    @property
    def template(self) -> Template:
        return self._template

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
            sec_nanosec(stamp_ns),
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


@dataclass(frozen=True)
class JointStateData:
    stamp_ns: int
    name: list[str]
    position: Vector
    velocity: Vector
    effort: Vector


class _TemplateDecoder:
    """A message type's quick path: the slots' values of a message with the template's layout; another layout
    is checked against ``limits`` from its length fields first (``SizeError``), if given, for rosbags' reader."""

    def __init__(self, typename: str, spec: dict[str, Any], limits: MessageLimits | None) -> None:
        self._typename, self._limits = typename, limits
        self._template = derive_template(typename, spec)
        bracing_typestore().get_msgdef(typename)  # the general reader's code, generated now

    @property
    def template(self) -> Template:
        return self._template

    def _values(self, data: bytes) -> list[tuple[Any, ...]] | None:
        """The slots' values, or None for another layout (checked against ``limits``)."""
        values = self._template.read(data)
        if values is None and self._limits is not None:
            check_cdr_sizes(bracing_typestore(), self._typename, data, self._limits)
        return values


class JointStateDecoder(_TemplateDecoder):
    """Reads JointStates, quickly when they have the layout of ``JointStateEncoder(names)``."""

    def __init__(self, names: Sequence[str], limits: MessageLimits | None = None) -> None:
        super().__init__(JOINT_STATE, _joint_state_spec(names, ""), limits)
        self._names = list(names)

    def decode(self, data: bytes) -> JointStateData:
        values = self._values(data)
        if values is None:
            return decode_joint_state(data)
        (sec, nanosec), position, velocity, effort = values
        return JointStateData(
            ns_of(sec, nanosec),
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


class MotorCommandDecoder(_TemplateDecoder):
    """Reads MotorCommands, quickly when they have the layout of ``MotorCommandEncoder(names, mode)``."""

    def __init__(self, names: Sequence[str], mode: int, limits: MessageLimits | None = None) -> None:
        super().__init__(MOTOR_COMMAND, _motor_command_spec(names, mode), limits)
        self._names, self._mode = list(names), mode

    def decode(self, data: bytes) -> MotorCommandData:
        values = self._values(data)
        if values is None:
            return decode_motor_command(data)
        (sec, nanosec), value = values
        return MotorCommandData(ns_of(sec, nanosec), self._mode, self._names.copy(), np.array(value))


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
