"""Child process for test_reset_simulation.py: records the simulator's joint_states (their CDR bytes) and calls its
reset_simulation service once, mid-run.

python reset_peer.py --reset-at T --duration D OUT
    Waits for the service, then subscribes to joint_states (the simulator waits for this subscriber too:
    min_subscribers 2, so no state is missed); at the first state stamped T [s] or later, calls
    reset_simulation; ends once, after the call, the state stamped D [s] (the run's end) has come, and writes
    {"states": [[stamp_ns, hex bytes], ...]} to OUT in the order received. Exit status 1 (and why) if the
    service or a state does not come in time.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Empty

from bracing_ros import wire

STATES_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10000, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)  # fmt: skip
TIMEOUT_S = 120.0


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reset-at", type=float, required=True)
    parser.add_argument("--duration", type=float, required=True)
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node("reset_peer")
    client = node.create_client(Empty, "reset_simulation")
    if not client.wait_for_service(timeout_sec=TIMEOUT_S):
        print("reset_simulation did not appear", file=sys.stderr)
        return 1
    states: list[tuple[int, bytes]] = []
    node.create_subscription(
        JointState, "joint_states", lambda data: states.append(stamped(data)), STATES_QOS, raw=True
    )
    reset_ns, end_ns = round(args.reset_at * 1e9), round(args.duration * 1e9)
    called = None
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
        if called is None and states and states[-1][0] >= reset_ns:
            called = client.call_async(Empty.Request())
        if called is not None and called.done() and any(stamp == end_ns for stamp, _ in states[-5:]):
            args.out.write_text(json.dumps({"states": [[stamp, data.hex()] for stamp, data in states]}))
            return 0
    print(f"no end of the run after the reset within {TIMEOUT_S:g} s ({len(states)} states)", file=sys.stderr)
    return 1


def stamped(data: bytes) -> tuple[int, bytes]:
    return wire.decode_joint_state(data).stamp_ns, data


if __name__ == "__main__":
    sys.exit(main())
