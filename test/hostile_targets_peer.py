"""Child process for test_hostile_targets.py: a careless, then hostile, sender of targets, printing what
it saw as JSON.

python hostile_targets_peer.py X Y Z FLOOD_DY
    Once the run passes t = 0.2 s (controller_state), in order, each step once the controller has said
    what it made of the one before (on hand_target/accepted, hand_target/refused, hand_path/refused):
    1. the hand target (X, Y, Z), the same message again on each of 100 controller_states;
    2. a hand_path entirely in the past (poses at 0.05 and 0.1 s);
    3. a hand_path 56 years ahead (a wall-clock stamp: 1.77e9 s);
    4. a hand_path of 100,000 poses (all at the target, 10 us apart from 1 s ahead);
    5. a hand_path whose frame_id is 100,000 characters long;
    6. a flood: 40 hand_targets on each of 50 controller_states, moving from the target to FLOOD_DY
       along y from it, the last exactly there;
    7. once the flood's last target is taken, a flood the controller must refuse: 20 hand_targets in frame
       base_link on each of 20 states.
    It records the controller_state's desired hand, every echo it hears, and the wall time from sending
    the long path to hearing it refused.
python hostile_targets_peer.py effort X Y Z
    Against a controller with command_output effort_forward: publishes joint_states (the paper's start,
    stamped 10 s) as joint_state_broadcaster would, sends a hand_path in the past (poses at 0.05 and
    0.1 s) once the controller answers one with a command, then, once the path is refused, the hand target
    (X, Y, Z); records the verdicts (EFFORT_GIVE_UP_S at most).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import Path
from ros2_control_peer import _follow_run, _stamp, _time_msg

from bracing_msgs.msg import ControllerState

T_START = 0.2  # [s] sim time of the first step
EFFORT_GIVE_UP_S = 60.0  # [s] effort: the wait for both verdicts, which only ends a hang
REPEATS = 100
FLOOD_STATES, FLOOD_PER_STATE = 50, 40
BAD_FLOOD_STATES, BAD_FLOOD_PER_STATE = 20, 20
LONG_PATH_POSES = 100_000
FIFTY_SIX_YEARS_S = 1.77e9


def point_msg(p: list[float], frame: str = "world") -> PointStamped:
    msg = PointStamped()
    msg.header.frame_id = frame
    msg.point.x, msg.point.y, msg.point.z = (float(v) for v in p)
    return msg


def path_msg(poses: list[tuple[float, list[float]]], frame: str = "world") -> Path:
    path = Path()
    path.header.frame_id = frame
    for t, p in poses:
        pose = PoseStamped()
        pose.header.stamp = _time_msg(t)
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = p
        pose.pose.orientation.w = 1.0
        path.poses.append(pose)
    return path


def effort() -> None:
    """See the module docstring (``effort``)."""
    from rclpy.qos import qos_profile_system_default
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    target = [float(v) for v in sys.argv[2:5]]
    rclpy.init()
    node = rclpy.create_node("hostile_targets_peer")
    states = node.create_publisher(JointState, "joint_states", qos_profile_system_default)
    point_pub = node.create_publisher(PointStamped, "hand_target", 10)
    path_pub = node.create_publisher(Path, "hand_path", 10)
    verdicts: list[list[str]] = []
    commands: list[Float64MultiArray] = []
    heard = [
        node.create_subscription(
            DiagnosticStatus, "hand_path/refused", lambda m: verdicts.append(["refused", m.message]), 10
        ),
        node.create_subscription(PointStamped, "hand_target/accepted", lambda m: verdicts.append(["accepted", ""]), 10),
        node.create_subscription(Float64MultiArray, "effort_controller/commands", commands.append, 10),
    ]
    q = [-0.6283185307179586, -1.8849555921538759, 2.5132741228718345, -1.2566370614359172]
    state = JointState(name=["joint1", "joint2", "joint3", "joint4"], position=q, velocity=[0.0] * 4)
    state.header.stamp.sec = 10
    while (
        min(pub.get_subscription_count() for pub in (states, point_pub, path_pub)) < 1
        or min(sub.get_publisher_count() for sub in heard) < 1
    ):
        rclpy.spin_once(node, timeout_sec=0.05)
    give_up, sent = time.monotonic() + EFFORT_GIVE_UP_S, 0
    while time.monotonic() < give_up and len(verdicts) < 2:
        states.publish(state)
        if sent == 0 and commands:  # the controller answers a state: its time is the states' 10 s
            path_pub.publish(path_msg([(0.05, target), (0.1, target)]))
            sent = 1
        elif sent == 1 and verdicts:
            point_pub.publish(point_msg(target))
            sent = 2
        rclpy.spin_once(node, timeout_sec=0.01)
    print(json.dumps({"verdicts": verdicts}))
    node.destroy_node()
    rclpy.shutdown()


def main() -> None:
    if sys.argv[1] == "effort":
        effort()
        return
    target = [float(v) for v in sys.argv[1:4]]
    flood_dy = float(sys.argv[4])
    rclpy.init()
    node = rclpy.create_node("hostile_targets_peer")
    point_pub = node.create_publisher(PointStamped, "hand_target", 10)
    path_pub = node.create_publisher(Path, "hand_path", 10)
    accepted: list[list[float]] = []  # x, y, z and the stamp of the state from which the controller follows it
    refused: list[dict[str, object]] = []
    rows: list[list[float]] = []
    out: dict[str, object] = {"rows": rows, "accepted": accepted, "refused": refused}

    def on_refused(msg: DiagnosticStatus) -> None:
        values = {v.key: v.value for v in msg.values}
        refused.append({"topic": msg.name, "kind": values.get("kind"), "count": int(values.get("refused", 0))})
        if values.get("kind") == "too many poses":
            out["long_path_refused_at"] = time.monotonic()

    def on_accepted(msg: PointStamped) -> None:
        accepted.append([msg.point.x, msg.point.y, msg.point.z, msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9])

    node.create_subscription(PointStamped, "hand_target/accepted", on_accepted, 1000)
    node.create_subscription(DiagnosticStatus, "hand_target/refused", on_refused, 1000)
    node.create_subscription(DiagnosticStatus, "hand_path/refused", on_refused, 1000)
    # built before the run: building it takes this process ~1 s
    long_path = path_msg([(1.0 + k * 1e-5, target) for k in range(LONG_PATH_POSES)])
    steps = _steps(target, flood_dy, point_pub, path_pub, long_path, out)
    progress = {"step": 0, "states": 0, "verdicts_before": -1}  # verdicts heard when the step before began

    def on_state(msg: ControllerState) -> None:
        t = _stamp(msg)
        d = msg.hand_desired
        rows.append([t, d.x, d.y, d.z])
        if t < T_START or progress["step"] >= len(steps):
            return
        verdicts = len(accepted) + len(refused)
        if progress["states"] == 0:
            if verdicts <= progress["verdicts_before"]:
                return  # the step before has no verdict yet
            starting = verdicts
        done = steps[progress["step"]](t, progress["states"])
        progress["states"] += 1
        if progress["states"] == 1:
            progress["verdicts_before"] = starting
        if done:
            progress["step"] += 1
            progress["states"] = 0
        out["steps_done"] = progress["step"]

    _follow_run(node, on_state, [point_pub, path_pub], rows)
    if "long_path_sent" in out and "long_path_refused_at" in out:
        out["long_path_refused_after_s"] = float(out["long_path_refused_at"]) - float(out["long_path_sent"])  # type: ignore[arg-type]
    print(json.dumps(out))
    node.destroy_node()
    rclpy.shutdown()


def _steps(
    target: list[float], flood_dy: float, point_pub: object, path_pub: object, long_path: Path, out: dict
) -> list[Callable[[float, int], bool]]:
    """Each step: called with the sim time and how many states it has been called on; True once done."""
    flood = np.linspace(0.0, flood_dy, FLOOD_STATES * FLOOD_PER_STATE)  # the last one: exactly flood_dy

    def repeat(t: float, k: int) -> bool:
        point_pub.publish(point_msg(target))  # type: ignore[attr-defined]
        return k + 1 >= REPEATS

    def past(t: float, k: int) -> bool:
        path_pub.publish(path_msg([(0.05, target), (0.1, target)]))  # type: ignore[attr-defined]
        return True

    def ahead(t: float, k: int) -> bool:
        path_pub.publish(path_msg([(FIFTY_SIX_YEARS_S, target), (FIFTY_SIX_YEARS_S + 1.0, target)]))  # type: ignore[attr-defined]
        return True

    def long(t: float, k: int) -> bool:
        out["long_path_sent"] = time.monotonic()
        path_pub.publish(long_path)  # type: ignore[attr-defined]
        return True

    def long_name(t: float, k: int) -> bool:
        path_pub.publish(path_msg([(t + 1.0, target)], frame="w" * 100_000))  # type: ignore[attr-defined]
        return True

    def flood_step(t: float, k: int) -> bool:
        if k == 0:
            out["flood_from"] = t
        for dy in flood[k * FLOOD_PER_STATE : (k + 1) * FLOOD_PER_STATE]:
            point_pub.publish(point_msg([target[0], target[1] + dy, target[2]]))  # type: ignore[attr-defined]
        if k + 1 >= FLOOD_STATES:
            out["flood_to"] = t
            return True
        return False

    flooded = 0

    def bad_flood(t: float, k: int) -> bool:
        nonlocal flooded
        last = out["accepted"][-1]  # type: ignore[index]
        if not flooded and last[1] != target[1] + flood_dy:
            return False  # the flood's last target not taken yet: this one would supersede it (the latest wins)
        for _ in range(BAD_FLOOD_PER_STATE):
            point_pub.publish(point_msg(target, frame="base_link"))  # type: ignore[attr-defined]
        flooded += 1
        return flooded >= BAD_FLOOD_STATES

    return [repeat, past, ahead, long, long_name, flood_step, bad_flood]


if __name__ == "__main__":
    main()
