"""Child process for the node tests: drives one node over DDS and prints what it saw as JSON.

python lockstep_driver.py sim N          -> plays controller for the simulator node: answers
    each joint_states with a known voltage sequence (joint names shuffled), N states
python lockstep_driver.py controller F   -> plays simulator for the controller node: publishes
    the joint states in JSON file F one by one and collects the motor_command answers
python lockstep_driver.py sim-bad N      -> as sim, but every valid command is preceded by
    malformed ones (NaN, inf, wrong length, unknown/duplicate names, wrong mode, stale and
    future stamps)
python lockstep_driver.py sim-skip N K   -> as sim, but never answers state K (watchdog)
python lockstep_driver.py sim-scale N S  -> as sim, with every command multiplied by S
python lockstep_driver.py sim-absurd N K -> as sim, but answers state K with 1e300 on every joint
    (finite, valid, but its step is not) and nothing else
python lockstep_driver.py sim-kinds F    -> as sim, answering state k with a bad command of kind F[k]
    (a JSON list of BAD_COMMAND_KINDS) and then the valid one (saturated / absurd / watchdog: the
    over-limit command, the 1e300 one, or nothing, instead)
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time

import rclpy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from bracing_msgs.msg import MotorCommand
from bracing_ros.qos import STREAM_QOS

JOINTS = ["joint1", "joint2", "joint3", "joint4"]
SHUFFLED = [3, 0, 2, 1]


def known_command(k: int) -> list[float]:
    """The known input sequence of the simulator test: a few volts, varying per step and joint."""
    return [2.0 * ((k * (j + 3)) % 7 - 3) / 3.0 + 0.5 * j for j in range(4)]


def bad_command_kinds(msg: JointState, values: list[float]) -> dict[str, MotorCommand | bytes]:
    """One command for each way a command can be wrong, including bytes that are no command,
    by the kind the simulator reports it under."""

    def make(names: list[str], vals: list[float], mode: int = MotorCommand.VOLTAGE, dt_ns: int = 0) -> MotorCommand:
        command = MotorCommand(mode=mode, name=names, value=vals)
        total = max(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec + dt_ns, 0)  # no stale one at k = 0
        command.header.stamp.sec, command.header.stamp.nanosec = divmod(total, 10**9)
        return command

    kinds: dict[str, MotorCommand | bytes] = {
        "nan": make(JOINTS, [float("nan"), *values[1:]]),
        "inf": make(JOINTS, [*values[:3], float("inf")]),
        "length": make(JOINTS, values[:3]),
        "missing-names": make(JOINTS[:3], values[:3]),
        "unknown-names": make([*JOINTS[:3], "joint9"], values),
        "duplicate": make([*JOINTS[:3], "joint1"], values),
        "mode-1": make(JOINTS, [v * 1e6 for v in values], mode=MotorCommand.TORQUE),
        "mode-7": make(JOINTS, values, mode=7),
        "from the future": make(JOINTS, [v + 100.0 for v in values], dt_ns=+1_000_000),
        "cut-short": serialize_message(make(JOINTS, [v + 100.0 for v in values]))[:30],
        "malformed": b"\x00\x01\x00\x00" + b"\xff" * 40,  # a string longer than the message
    }
    if msg.header.stamp.nanosec or msg.header.stamp.sec:  # no stale one at k = 0
        kinds["stale"] = make(JOINTS, [v + 100.0 for v in values], dt_ns=-1_000_000)
    return kinds


# Kinds the sim-kinds driver sends instead of the valid command.
INSTEAD_KINDS = {"saturated", "absurd", "watchdog"}


def bad_commands(msg: JointState, values: list[float]) -> list[MotorCommand | bytes]:
    """One command for each way a command can be wrong, including bytes that are no command."""
    return list(bad_command_kinds(msg, values).values())


def drive_simulator(
    node: rclpy.node.Node, steps: int, mode: str = "sim", arg: float = 0.0, kinds: list[str] | None = None
) -> dict[str, object]:
    states: list[dict[str, object]] = []
    kinds = kinds or []
    pub = node.create_publisher(MotorCommand, "motor_command", STREAM_QOS)

    def on_state(msg: JointState) -> None:
        k = len(states)
        states.append(
            {
                "stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec],
                "name": list(msg.name),
                "position": list(msg.position),
                "velocity": list(msg.velocity),
                "effort": list(msg.effort),
            }
        )
        values = known_command(k)
        if mode == "sim-skip" and k == int(arg):
            return
        if mode == "sim-absurd" and k == int(arg):
            values = [1e300] * len(values)
        if mode == "sim-kinds":
            kind = kinds[k] if k < len(kinds) else "none"
            if kind in INSTEAD_KINDS:
                if kind == "watchdog":
                    return
                values = [1e300 if kind == "absurd" else 1e6] * len(values)
            elif kind != "none":
                pub.publish(bad_command_kinds(msg, values)[kind])
        if mode == "sim-scale":
            values = [v * arg for v in values]
        if mode == "sim-bad":
            for bad in bad_commands(msg, values):
                pub.publish(bad)
        command = MotorCommand(
            mode=MotorCommand.VOLTAGE, name=[JOINTS[j] for j in SHUFFLED], value=[values[j] for j in SHUFFLED]
        )
        command.header.stamp = msg.header.stamp
        pub.publish(command)

    node.create_subscription(JointState, "joint_states", on_state, STREAM_QOS)
    deadline = time.monotonic() + float(os.environ.get("DRIVER_TIMEOUT", "120"))
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
        if "raw_hex" in state:  # bytes that are no JointState
            pub.publish(bytes.fromhex(state["raw_hex"]))
            if not state.get("no_wait"):
                time.sleep(0.5)
            continue
        msg = JointState(
            name=state["name"], position=state["position"], velocity=state["velocity"], effort=state.get("effort", [])
        )
        msg.header.stamp.sec, msg.header.stamp.nanosec = k // 1000, (k % 1000) * 1_000_000  # t = k ms
        if "stamp" in state:
            msg.header.stamp.sec, msg.header.stamp.nanosec = state["stamp"]
        pub.publish(msg)
        if state.get("no_wait"):  # an answer is not expected: the next state's answer shows it was handled
            continue
        deadline = time.monotonic() + 3.0
        while k not in answers and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
    return {"answers": [answers.get(k) for k in range(len(inputs))]}


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("lockstep_driver")
    role = sys.argv[1]
    if role == "sim-kinds":
        with open(sys.argv[2]) as handle:
            kinds = json.load(handle)
        result = drive_simulator(node, len(kinds) + 1, role, kinds=kinds)
    elif role.startswith("sim"):
        result = drive_simulator(node, int(sys.argv[2]), role, float(sys.argv[3]) if len(sys.argv) > 3 else 0.0)
    else:
        result = drive_controller(node, sys.argv[2])
    print(json.dumps(result), flush=True)
    # The result is out. Tear down (the node under test sees this reader leave at once, instead of
    # after DDS's 20 s lease), but give up after 10 s: seen twice in CI, this process spun at 100 %
    # CPU in destroy_node / shutdown until the test's 180 s timeout, failing a complete result.
    teardown = threading.Thread(target=lambda: (node.destroy_node(), rclpy.try_shutdown()), daemon=True)
    teardown.start()
    teardown.join(10.0)
    os._exit(0)


if __name__ == "__main__":
    main()
