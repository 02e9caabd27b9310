"""Child process for test_messages: publish or receive every bracing_msgs message.

python msg_echo.py send   -> publishes one filled instance of each message type, repeatedly
python msg_echo.py receive -> prints one JSON line per type received, then exits
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from geometry_msgs.msg import Point, Vector3
from rclpy.qos import QoSProfile, ReliabilityPolicy

from bracing_msgs.msg import Contacts, ContactState, ControllerState, MotorCommand, MotorState

QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def message_to_ordereddict(msg: object) -> object:
    """Every field of a rosidl message, recursively, as JSON-able values."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {field: message_to_ordereddict(getattr(msg, field)) for field in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "array":
        return [message_to_ordereddict(v) for v in msg]
    return msg


def samples() -> dict[str, object]:
    command = MotorCommand(mode=MotorCommand.TORQUE, name=["joint2", "joint1"], value=[1.5, -2.25])
    command.header.stamp.sec, command.header.stamp.nanosec = 3, 1000
    state = MotorState(
        name=["joint1"],
        voltage=[12.0],
        current=[0.5],
        power=[6.0],
        energy_consumed=1.25,
        energy_net=-0.5,
        copper_loss=0.125,
        temperature=[31.5],
    )
    state.header.frame_id = "motors"
    contact = ContactState(
        name="elbow",
        frame="elbow",
        active=True,
        position=Point(x=0.0, y=0.5878, z=1e-12),
        normal=Vector3(x=0.0, y=0.0, z=1.0),
        normal_force=10.0,
        friction_force=1.0,
        slip_velocity=Vector3(x=0.0, y=-0.01, z=0.0),
        residual=-3e-15,
    )
    contacts = Contacts(contacts=[contact, ContactState(name="knee", active=False)])
    controller = ControllerState(
        hand_desired=Point(x=0.0, y=1.3, z=0.6),
        hand_actual=Point(x=0.0, y=1.29, z=0.61),
        contact_name=["elbow"],
        desired_normal_force=[10.0],
        brace_desired=[Point(y=0.5878)],
        brace_actual=[Point(y=0.58)],
        command=[1.0, 2.0, 3.0, 4.0],
        compute_time=2.5e-5,
    )
    return {
        "MotorCommand": command,
        "MotorState": state,
        "Contacts": contacts,
        "ControllerState": controller,
        "ContactState": contact,
    }


def main() -> None:
    role = sys.argv[1]
    rclpy.init()
    node = rclpy.create_node(f"msg_{role}")
    msgs = samples()
    if role == "send":
        pubs = {name: node.create_publisher(type(msg), f"test_{name}", QOS) for name, msg in msgs.items()}
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            for name, msg in msgs.items():
                pubs[name].publish(msg)
            rclpy.spin_once(node, timeout_sec=0.05)
    else:
        received: dict[str, object] = {}

        def keep(name: str):
            return lambda msg: received.setdefault(name, message_to_ordereddict(msg))

        subs = [node.create_subscription(type(msg), f"test_{name}", keep(name), QOS) for name, msg in msgs.items()]
        deadline = time.monotonic() + (float(sys.argv[2]) if len(sys.argv) > 2 else 25.0)
        while len(received) < len(msgs) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        del subs
        expected = {name: message_to_ordereddict(msg) for name, msg in msgs.items()}
        print(json.dumps({"received": received, "expected": expected}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
