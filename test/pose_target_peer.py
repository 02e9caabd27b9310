"""Child process for test_hand_pose_target.py: a sender of hand_pose_target, printing what it saw as JSON.

python pose_target_peer.py X Y Z QX QY QZ QW
    Once the run passes t = 0.2 s (controller_state), in order, each once the controller has said what it made
    of the one before (hand_pose_target/accepted or /refused): the pose in frame base_link; the pose with a
    zero quaternion; the pose (X, Y, Z; QX, QY, QZ, QW) in world. Prints the verdicts (each with the stamp of
    the state from which an accepted pose is followed) once the run has ended.
"""

from __future__ import annotations

import json
import sys

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from ros2_control_peer import _follow_run, _stamp

from bracing_msgs.msg import ControllerState

T_START = 0.2  # [s] sim time of the first pose sent


def pose_msg(values: list[float], frame: str = "world") -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = frame
    p, o = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z, o.x, o.y, o.z, o.w = values
    return msg


def main() -> None:
    pose = [float(v) for v in sys.argv[1:8]]
    sends = [pose_msg(pose, "base_link"), pose_msg([*pose[:3], 0.0, 0.0, 0.0, 0.0]), pose_msg(pose)]
    rclpy.init()
    node = rclpy.create_node("pose_target_peer")
    pub = node.create_publisher(PoseStamped, "hand_pose_target", 10)
    verdicts: list[dict[str, object]] = []
    rows: list[float] = []

    def on_refused(msg: DiagnosticStatus) -> None:
        values = {v.key: v.value for v in msg.values}
        verdicts.append({"verdict": "refused", "kind": values.get("kind"), "message": msg.message})

    def on_accepted(msg: PoseStamped) -> None:
        o = msg.pose.orientation
        verdicts.append({"verdict": "accepted", "t": _stamp(msg), "orientation": [o.x, o.y, o.z, o.w]})

    node.create_subscription(DiagnosticStatus, "hand_pose_target/refused", on_refused, 100)
    node.create_subscription(PoseStamped, "hand_pose_target/accepted", on_accepted, 100)

    sent = [0]  # poses sent so far: the next goes once each has its verdict (the latest of a topic wins)

    def on_state(msg: ControllerState) -> None:
        t = _stamp(msg)
        rows.append(t)
        if t >= T_START and sent[0] < len(sends) and len(verdicts) == sent[0]:
            pub.publish(sends[sent[0]])
            sent[0] += 1

    _follow_run(node, on_state, [pub], rows)
    print(json.dumps({"verdicts": verdicts, "states": len(rows)}))
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
