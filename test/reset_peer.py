"""Child process for test_reset_simulation.py: records the simulator's joint_states (their CDR bytes) and calls its
reset_simulation service once, mid-run.

python reset_peer.py --reset-at T --duration D OUT
    Waits for the service, then subscribes to joint_states (the simulator waits for this subscriber too:
    min_subscribers 2, so no state is missed); at the first state stamped T [s] or later, calls
    reset_simulation; ends once the states have gone back in time (the reset's effect: its response is not
    awaited, as Fast DDS may drop a response whose reader the server has not matched yet) and the state
    stamped D [s] (the run's end) has come after that, and writes {"states": [[stamp_ns, hex bytes], ...]} to
    OUT in the order received. Exit status 1 (and why) if the service or a state does not come in time.
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
TIMEOUT_S = 90.0  # [s] for the service, then again for the two runs


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
        if called is not None and ended_after_going_back(states, end_ns):
            args.out.write_text(json.dumps({"states": [[stamp, data.hex()] for stamp, data in states]}))
            return 0
    said = "no reset_simulation called" if called is None else f"reset answered: {called.done()}"
    stamps = [stamp for stamp, _ in states]
    print(
        f"no end of the run after the reset within {TIMEOUT_S:g} s ({len(states)} states, {said}, "
        f"went back in time at {[k for k in range(1, len(stamps)) if stamps[k] < stamps[k - 1]]}, "
        f"last stamp {stamps[-1] if stamps else None} ns)",
        file=sys.stderr,
    )
    return 1


def ended_after_going_back(states: list[tuple[int, bytes]], end_ns: int) -> bool:
    """Whether the run's last state (``end_ns``) has come after the states went back in time."""
    if not any(stamp == end_ns for stamp, _ in states[-5:]):
        return False
    stamps = [stamp for stamp, _ in states]
    back = next((k for k in range(1, len(stamps)) if stamps[k] < stamps[k - 1]), None)
    return back is not None and end_ns in stamps[back:]


def stamped(data: bytes) -> tuple[int, bytes]:
    return wire.decode_joint_state(data).stamp_ns, data


if __name__ == "__main__":
    sys.exit(main())
