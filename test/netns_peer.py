"""Child process for test_loopback: a participant on the other side of the network.

    python netns_peer.py --seconds S --joints joint1,joint2,...

Run in another network namespace with ROS_STATIC_PEERS naming this machine's address there, it
tries for at most ``S`` seconds (or until SIGINT) to discover a bracing run in its ROS_DOMAIN_ID
and to inject motor commands (stamped 12345 s, a time no state has: the simulator would reject
each by name). It publishes 20 commands a second, and only to subscriptions it matched. It prints
``ready`` once its node exists, then one JSON line of what it saw: the most subscriptions its
command publisher matched, the joint_states it received, the node names it discovered.
"""

from __future__ import annotations

import argparse
import json
import signal
import time

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState

from bracing_msgs.msg import MotorCommand

QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
INJECTED_STAMP_S = 12345


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, required=True)
    parser.add_argument("--joints", required=True)
    args = parser.parse_args()
    signal.signal(signal.SIGINT, signal.default_int_handler)  # stop early, still report
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("intruder")
    publisher = node.create_publisher(MotorCommand, "motor_command", QOS)
    seen = {"matched": 0, "joint_states": 0, "nodes": set()}

    def on_state(_: JointState) -> None:
        seen["joint_states"] += 1

    node.create_subscription(JointState, "joint_states", on_state, QOS)
    command = MotorCommand(mode=MotorCommand.VOLTAGE, name=args.joints.split(","))
    command.value = [0.0] * len(command.name)
    command.header.stamp.sec = INJECTED_STAMP_S
    print("ready", flush=True)
    now = time.monotonic()
    deadline, next_command = now + args.seconds, now
    try:
        while now < deadline:
            rclpy.spin_once(node, timeout_sec=max(next_command - now, 0.0))
            now = time.monotonic()
            if now >= next_command:  # 20 a second, however many states come in
                next_command = now + 0.05
                publisher.publish(command)
                seen["matched"] = max(seen["matched"], publisher.get_subscription_count())
                seen["nodes"] |= set(node.get_node_names())
    except KeyboardInterrupt:
        pass
    print(json.dumps({**seen, "nodes": sorted(seen["nodes"])}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
