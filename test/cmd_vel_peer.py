"""Child process for test_mobile_ros.py: a teleop sending cmd_vel (geometry_msgs/TwistStamped), as a user's
joystick or a navigation stack would, printing what it sent as JSON.

python cmd_vel_peer.py SPEED START STOP
    Follows the run's controller_state; from sim time START [s] to STOP, every 0.1 s of sim time, sends a
    TwistStamped stamped with that sim time: first one whose linear.x is NaN, then one stamped 0.55 s in the past
    (the controller refuses both; START >= 0.55), then linear.x = SPEED [m/s]. One at a time: the system
    default QoS (diff_drive_controller's) keeps the latest only. Prints the stamps of the valid ones once the
    run has ended.
"""

from __future__ import annotations

import json
import math
import sys

import rclpy
from geometry_msgs.msg import TwistStamped
from rclpy.qos import qos_profile_system_default
from ros2_control_peer import _follow_run, _stamp

from bracing_msgs.msg import ControllerState


def twist(t: float, speed: float) -> TwistStamped:
    msg = TwistStamped()
    sec = math.floor(t)
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, round((t - sec) * 1e9)
    msg.header.frame_id = "base_link"
    msg.twist.linear.x = speed
    return msg


def main() -> None:
    speed, start, stop = (float(v) for v in sys.argv[1:4])
    rclpy.init()
    node = rclpy.create_node("cmd_vel_peer")
    pub = node.create_publisher(TwistStamped, "cmd_vel", qos_profile_system_default)
    sent: list[float] = []
    refused: list[float] = []
    rows: list[float] = []

    def on_state(msg: ControllerState) -> None:
        t = _stamp(msg)
        rows.append(t)
        due = start + 0.1 * (len(refused) + len(sent))
        if t + 1e-9 < due or due > stop + 1e-9 or pub.get_subscription_count() < 2:
            return  # not yet; or the controller and the recorder do not both hear it yet (volatile: it would be lost)
        if len(refused) == 0:
            pub.publish(twist(t, math.nan))  # refused: not finite
        elif len(refused) == 1:
            pub.publish(twist(t - 0.55, 5.0 * speed))  # refused: older than cmd_vel_timeout (0.5 s)
        else:
            pub.publish(twist(t, speed))
            sent.append(t)
            return
        refused.append(t)

    _follow_run(node, on_state, [pub], rows)
    print(json.dumps({"sent": sent, "states": len(rows)}))
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
