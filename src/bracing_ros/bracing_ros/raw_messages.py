"""Messages taken raw (CDR bytes) decoded by ``wire``, or by rclpy for encodings ``wire`` does not read."""

from __future__ import annotations

import struct
from typing import Any

from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from bracing_core.message_limits import MessageLimits
from bracing_msgs.msg import MotorCommand
from bracing_ros import wire


def read_joint_state(data: bytes, decoder: wire.JointStateDecoder) -> wire.JointStateData:
    """A JointState taken raw (CDR bytes); rclpy decodes encapsulations ``wire`` does not read.

    Raises ``wire.DecodeError`` for bytes that are not a JointState.
    """
    try:
        return decoder.decode(data)
    except wire.UnsupportedEncoding:
        return wire.joint_state_data(deserialize(data, JointState))


def read_motor_command(data: bytes, decoder: wire.MotorCommandDecoder) -> wire.MotorCommandData:
    """A MotorCommand taken raw (CDR bytes); see :func:`read_joint_state`."""
    try:
        return decoder.decode(data)
    except wire.UnsupportedEncoding:
        return wire.motor_command_data(deserialize(data, MotorCommand))


def read_checked(data: bytes, typename: str, msg_type: type, limits: MessageLimits) -> Any:
    """A message of ``typename`` (``msg_type``, rclpy's class) taken raw (CDR bytes), its sizes checked
    against ``limits`` before its elements are decoded (``SizeError``); see :func:`read_joint_state`."""
    try:
        return wire.decode_checked(data, typename, limits)
    except wire.UnsupportedEncoding:
        return deserialize(data, msg_type)


def deserialize(data: bytes, msg_type: type) -> Any:
    """rclpy's message of ``data``, or ``wire.DecodeError`` saying why it cannot be read."""
    try:
        return deserialize_message(data, msg_type)
    except Exception as exc:  # rclpy raises its RMWError (and others) for bytes it cannot read
        raise wire.DecodeError(str(exc).split(", at /")[0]) from None


def path_sizes(data: bytes) -> tuple[int, int] | None:
    """(characters of its header's frame_id, poses) of a nav_msgs/Path taken raw, read from its first
    bytes without touching a pose; None for an encapsulation this does not read (plain CDR only).

    Raises ``wire.DecodeError`` for bytes too short to hold them."""
    if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):  # CDR_BE, CDR_LE
        return None
    order = "<" if data[1] == 1 else ">"
    try:
        # encapsulation (4), stamp sec + nanosec (8), then frame_id: its length (NUL included) and bytes;
        # the pose count is 4-aligned (relative to the encapsulation's end: the same, it is 4 bytes)
        (length,) = struct.unpack_from(order + "I", data, 12)
        at = 16 + length
        (poses,) = struct.unpack_from(order + "I", data, at + (-at % 4))
    except struct.error:
        raise wire.DecodeError(f"{len(data)} bytes: too short for a nav_msgs/Path") from None
    return max(length - 1, 0), poses
