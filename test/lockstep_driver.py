"""Child process for the node tests: drives one node over DDS and prints what it saw as JSON.

    python lockstep_driver.py sim N          -> plays controller for the simulator node: answers
        each joint_states with a known voltage sequence (joint names shuffled), N states
    python lockstep_driver.py controller F   -> plays simulator for the controller node: publishes
        the joint states in JSON file F one by one and collects the motor_command answers
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from bracing_msgs.msg import MotorCommand
from sensor_msgs.msg import JointState

from bracing_sim.ros_common import STREAM_QOS

JOINTS = ["joint1", "joint2", "joint3", "joint4"]
SHUFFLED = [3, 0, 2, 1]


def known_command(k: int) -> list[float]:
    """The known input sequence of the simulator test: a few volts, varying per step and joint."""
    return [2.0 * ((k * (j + 3)) % 7 - 3) / 3.0 + 0.5 * j for j in range(4)]


def drive_simulator(node: rclpy.node.Node, steps: int) -> dict[str, object]:
    states: list[dict[str, object]] = []
    pub = node.create_publisher(MotorCommand, "motor_command", STREAM_QOS)

    def on_state(msg: JointState) -> None:
        k = len(states)
        states.append({"stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec], "name": list(msg.name),
                       "position": list(msg.position), "velocity": list(msg.velocity), "effort": list(msg.effort)})
        values = known_command(k)
        command = MotorCommand(mode=MotorCommand.VOLTAGE, name=[JOINTS[j] for j in SHUFFLED],
                               value=[values[j] for j in SHUFFLED])
        command.header.stamp = msg.header.stamp
        pub.publish(command)

    node.create_subscription(JointState, "joint_states", on_state, STREAM_QOS)
    deadline = time.monotonic() + 120.0
    while len(states) < steps and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    return {"states": states}


def drive_controller(node: rclpy.node.Node, path: str) -> dict[str, object]:
    with open(path) as handle:
        inputs = json.load(handle)
    answers: dict[int, dict[str, object]] = {}
    pub = node.create_publisher(JointState, "joint_states", STREAM_QOS)

    def on_command(msg: MotorCommand) -> None:
        k = msg.header.stamp.sec * 1000 + msg.header.stamp.nanosec // 1_000_000
        answers[k] = {"mode": msg.mode, "name": list(msg.name), "value": list(msg.value)}

    node.create_subscription(MotorCommand, "motor_command", on_command, STREAM_QOS)
    while pub.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    for k, state in enumerate(inputs):
        msg = JointState(name=state["name"], position=state["position"], velocity=state["velocity"])
        msg.header.stamp.sec, msg.header.stamp.nanosec = k // 1000, (k % 1000) * 1_000_000  # t = k ms
        pub.publish(msg)
        deadline = time.monotonic() + 10.0
        while k not in answers and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
    return {"answers": [answers.get(k) for k in range(len(inputs))]}


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("lockstep_driver")
    result = drive_simulator(node, int(sys.argv[2])) if sys.argv[1] == "sim" else drive_controller(node, sys.argv[2])
    print(json.dumps(result), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
