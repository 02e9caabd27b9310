"""Child process for test_ros2_control.py: rclpy peers that behave as ros2_control's components are
documented to (ros-controls/topic_based_hardware_interfaces, ros-controls/ros2_controllers), printing
what they saw as JSON.

python ros2_control_peer.py topic-system N PARAMS_JSON
    joint_state_topic_hardware_interface/JointStateTopicSystem with our torque law behind it: reads
    robot_joint_states with SensorDataQoS semantics (latest message), answers each state with our law's
    torques as sensor_msgs/JointState on robot_joint_commands (reliable, depth 1; names in its own,
    shuffled joint order, only `effort` filled), N states.
python ros2_control_peer.py effort-controller N
    effort_controllers/JointGroupEffortController: subscribes effort_controller/commands (reliable);
    publishes a state on joint_states (best effort, as SensorDataQoS), then one with NaN, then one
    missing a joint, and collects the Float64MultiArray commands (length, values) after each.
python ros2_control_peer.py target T_PUB X Y Z [FRAME]
    a script sending the hand a target: waits for controller_state at t >= T_PUB, publishes a
    PointStamped on hand_target, and records the controller_state's hand (desired, actual) until the run ends.
"""

from __future__ import annotations

import json
import math
import sys
import time

import numpy as np
import rclpy
from geometry_msgs.msg import PointStamped
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from bracing_msgs.msg import ControllerState

JOINTS = ["joint1", "joint2", "joint3", "joint4"]
SHUFFLED = [2, 0, 3, 1]
RELIABLE_1 = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE)


def _stamp(msg: JointState | ControllerState) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def topic_system(node: rclpy.node.Node, steps: int, params: dict[str, object]) -> dict[str, object]:
    from bracing_core.controller_config import ControllerConfig
    from bracing_core.law import DecoupledController

    law = DecoupledController(ControllerConfig.from_params(params))
    names = list(law.plant.joint_names)
    pub = node.create_publisher(JointState, "robot_joint_commands", RELIABLE_1)
    states: list[dict[str, object]] = []
    best_effort: list[float] = []

    def on_state(msg: JointState) -> None:
        index = {n: k for k, n in enumerate(msg.name)}
        q = np.array([msg.position[index[n]] for n in names])
        dq = np.array([msg.velocity[index[n]] for n in names])
        states.append({"t": _stamp(msg), "position": q.tolist(), "velocity": dq.tolist(), "effort": list(msg.effort)})
        tau = law.update(_stamp(msg), q, dq).command
        command = JointState(name=[names[j] for j in SHUFFLED], effort=[float(tau[j]) for j in SHUFFLED])
        command.header.stamp = msg.header.stamp
        pub.publish(command)

    # reliable for the physics check (no state may be lost); a SensorDataQoS subscription must match too
    node.create_subscription(JointState, "robot_joint_states", on_state, QoSProfile(depth=100))
    node.create_subscription(
        JointState, "robot_joint_states", lambda m: best_effort.append(_stamp(m)), qos_profile_sensor_data
    )
    deadline = time.monotonic() + 120
    while len(states) < steps and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    return {"states": states, "best_effort_received": len(best_effort)}


def effort_controller(node: rclpy.node.Node, _: int) -> dict[str, object]:
    commands: list[list[float]] = []
    node.create_subscription(
        Float64MultiArray, "effort_controller/commands", lambda m: commands.append(list(m.data)), 10
    )
    pub = node.create_publisher(JointState, "joint_states", qos_profile_sensor_data)
    while pub.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    q = [-0.6283185307179586, -1.8849555921538759, 2.5132741228718345, -1.2566370614359172]
    good = JointState(name=[JOINTS[j] for j in SHUFFLED], position=[q[j] for j in SHUFFLED], velocity=[0.0] * 4)
    bad_nan = JointState(name=JOINTS, position=[math.nan, *q[1:]], velocity=[0.0] * 4)
    missing = JointState(name=JOINTS[:3], position=q[:3], velocity=[0.0] * 3)
    seen: dict[str, list[list[float]]] = {}
    for label, msg in (("good", good), ("nan", bad_nan), ("missing", missing)):
        commands.clear()
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            pub.publish(msg)
            rclpy.spin_once(node, timeout_sec=0.01)
        time.sleep(0.1)
        commands.clear()  # whatever the previous state left in flight
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            pub.publish(msg)
            rclpy.spin_once(node, timeout_sec=0.01)
        seen[label] = list(commands)
    infos = node.get_publishers_info_by_topic("/effort_controller/commands")
    reliability = [str(i.qos_profile.reliability.name) for i in infos]
    return {"commands": seen, "publisher_reliability": reliability}


def target(node: rclpy.node.Node, t_pub: float, point: list[float], frame: str) -> dict[str, object]:
    pub = node.create_publisher(PointStamped, "hand_target", 10)
    rows: list[list[float]] = []
    sent: list[float] = []

    def on_state(msg: ControllerState) -> None:
        t = _stamp(msg)
        d, a = msg.hand_desired, msg.hand_actual
        rows.append([t, d.x, d.y, d.z, a.x, a.y, a.z])
        if not sent and t >= t_pub:
            for bad, bad_frame in (([0.0, 5.0, 5.0], "world"), (point, "base_link"), ([math.nan, 1.0, 0.6], "world")):
                bad_msg = PointStamped()
                bad_msg.header.frame_id = bad_frame
                bad_msg.point.x, bad_msg.point.y, bad_msg.point.z = bad
                pub.publish(bad_msg)
            target_msg = PointStamped()
            target_msg.header.frame_id = frame
            target_msg.point.x, target_msg.point.y, target_msg.point.z = point
            pub.publish(target_msg)
            sent.append(t)

    node.create_subscription(ControllerState, "controller_state", on_state, QoSProfile(depth=10000))
    deadline, quiet = time.monotonic() + 120, 0.0
    while time.monotonic() < deadline and quiet < 3.0:  # until the run has ended (3 s without a state)
        count = len(rows)
        rclpy.spin_once(node, timeout_sec=0.1)
        quiet = quiet + 0.1 if rows and len(rows) == count else 0.0
    return {"sent_at": sent, "rows": rows}


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("ros2_control_peer")
    kind = sys.argv[1]
    if kind == "topic-system":
        out = topic_system(node, int(sys.argv[2]), json.loads(sys.argv[3]))
    elif kind == "effort-controller":
        out = effort_controller(node, int(sys.argv[2]))
    else:
        frame = sys.argv[6] if len(sys.argv) > 6 else "world"
        out = target(node, float(sys.argv[2]), [float(v) for v in sys.argv[3:6]], frame)
    print(json.dumps(out))
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
