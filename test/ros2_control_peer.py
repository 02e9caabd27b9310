"""Child process for test_ros2_control.py: rclpy peers that behave as ros2_control's components are
documented to (ros-controls/topic_based_hardware_interfaces, ros-controls/ros2_controllers), printing
what they saw as JSON.

What each one does is read from the sources (HEAD of ros-controls/topic_based_hardware_interfaces
main, ros-controls/ros2_controllers jazzy):
- joint_state_topic_hardware_interface/src/joint_state_topic_hardware_interface.cpp: parameters
  joint_commands_topic (default /robot_joint_commands), joint_states_topic (/robot_joint_states),
  trigger_joint_command_threshold (1e-5; -1 sends every cycle); commands published with rclcpp::QoS(1)
  (reliable, volatile, depth 1), header.stamp = now, name[] of every joint in its order, only the
  declared command interfaces filled; state read with SensorDataQoS, joints by name.
- forward_command_controller/src/forward_controllers_base.cpp: ``~/commands`` with SystemDefaultsQoS,
  a message with a non-finite value dropped, a length other than its joints' an update error.
- joint_state_broadcaster/src/joint_state_broadcaster.cpp: ``joint_states`` with SystemDefaultsQoS,
  frame_id base_link, NaN for an interface a joint lacks.

python ros2_control_peer.py topic-system N PARAMS_JSON
    JointStateTopicSystem with our torque law behind it (joints declared in a shuffled order, effort
    command interfaces only, trigger_joint_command_threshold -1 as docs/guides/ros2-control.md sets it): answers each
    state on /robot_joint_states with our law's torques on /robot_joint_commands, N states.
python ros2_control_peer.py effort-controller N
    effort_controllers/JointGroupEffortController with joint_state_broadcaster: subscribes
    effort_controller/commands (SystemDefaultsQoS, refusing as the controller does) and publishes
    states on joint_states as the broadcaster does (SystemDefaultsQoS, NaN efforts) and as a
    SensorDataQoS publisher would, then one with NaN, then one missing a joint, and collects the
    accepted Float64MultiArray commands of each case, each until the controller shows it took its
    states (its own posture's command; a refused state's warning on /rosout, then the next posture's).
python ros2_control_peer.py path T_PUB PATH_JSON BRACE_DY
    a script at t >= T_PUB sending a nav_msgs/Path on hand_path (PATH_JSON: [[t, x, y, z], ...], each
    pose stamped t [s] in the controller's time, frame world) and the elbow's brace point moved by
    BRACE_DY along y on brace_target/elbow; records the controller_state's hand and elbow brace point, and
    the stamps of the controller's echoes (``taken``: the state each target was taken with).
python ros2_control_peer.py sim-clock
    the forward controller's side of a use_sim_time run: publishes /clock (frozen at 5 s for 1 s of wall
    time, then 10 ms a tick for 50 ticks, each once the tick before was answered or after
    TICK_ANSWER_WAIT_S) and joint_states, and counts the commands in each phase.
python ros2_control_peer.py constant-effort TAU_JSON
    JointStateTopicSystem holding one effort command (TAU_JSON, robot.joint_names order): sends it until
    the run ends, recording /clock, /robot_joint_states and motor_state.
python ros2_control_peer.py target T_PUB X Y Z [FRAME]
    a script sending the hand a target: waits for controller_state at t >= T_PUB, publishes three
    PointStamped on hand_target that the controller must refuse (each once it said it refused the one
    before, on hand_target/refused), then the target, and records the controller_state's hand (desired,
    actual) until the run ends.
The path and target scripts subscribe to joint_states once matched with the controller: the simulator
waits for them with min_subscribers 2.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import Path
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
    qos_profile_system_default,
)
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from bracing_msgs.msg import ControllerState

JOINTS = ["joint1", "joint2", "joint3", "joint4"]
SHUFFLED = [2, 0, 3, 1]
EFFORT_POSTURES = [
    [-0.6283185307179586 + 0.01 * k, -1.8849555921538759, 2.5132741228718345, -1.2566370614359172] for k in range(5)
]
"""effort-controller: the paper's start (the first) and four postures near it, each case's own: a command
tells which state it answers (postures 0-3 good, 4 the state missing a joint)."""
CASE_GIVE_UP_S = 60.0  # [s] effort-controller: each case's wait for what ends it, which only ends a hang
RELIABLE_1 = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""rclcpp::QoS(1): JointStateTopicSystem's command publisher."""


def _stamp(msg: JointState | ControllerState) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def topic_system(node: rclpy.node.Node, steps: int, params: dict[str, object]) -> dict[str, object]:
    from bracing_core.controller_config import ControllerConfig
    from bracing_core.law import DecoupledController

    law = DecoupledController(ControllerConfig.from_params(params))
    names = list(law.plant.joint_names)
    pub = node.create_publisher(JointState, "/robot_joint_commands", RELIABLE_1)
    threshold = -1.0  # trigger_joint_command_threshold, as docs/guides/ros2-control.md sets it
    states: list[dict[str, object]] = []
    best_effort: list[float] = []

    def on_state(msg: JointState) -> None:
        index = {n: k for k, n in enumerate(msg.name)}
        q = np.array([msg.position[index[n]] for n in names])
        dq = np.array([msg.velocity[index[n]] for n in names])
        states.append({"t": _stamp(msg), "position": q.tolist(), "velocity": dq.tolist(), "effort": list(msg.effort)})
        tau = law.update(_stamp(msg), q, dq).command
        # write(): skipped when sum |effort state - effort command| <= threshold
        if np.abs(np.array([msg.effort[index[n]] for n in names]) - tau).sum() <= threshold:
            return
        command = JointState(name=[names[j] for j in SHUFFLED], effort=[float(tau[j]) for j in SHUFFLED])
        command.header.stamp = node.get_clock().now().to_msg()
        pub.publish(command)

    # reliable for the physics check (no state may be lost); a SensorDataQoS subscription must match too
    node.create_subscription(JointState, "/robot_joint_states", on_state, QoSProfile(depth=100))
    node.create_subscription(
        JointState, "/robot_joint_states", lambda m: best_effort.append(_stamp(m)), qos_profile_sensor_data
    )
    deadline = time.monotonic() + 120
    while len(states) < steps and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    return {"states": states, "best_effort_received": len(best_effort)}


def forward_controller(node: rclpy.node.Node, joints: int) -> tuple[list[list[float]], list[str]]:
    """The forward controller's ``~/commands`` subscription: the accepted commands, and what it refused."""
    accepted: list[list[float]] = []
    refused: list[str] = []

    def on_command(msg: Float64MultiArray) -> None:
        data = list(msg.data)
        if not all(math.isfinite(v) for v in data):
            refused.append("non-finite")  # "Non-finite value received. Dropping message"
        elif len(data) != joints:
            refused.append("size")  # update(): "command size (%zu) does not match number of interfaces"
        else:
            accepted.append(data)

    node.create_subscription(Float64MultiArray, "effort_controller/commands", on_command, qos_profile_system_default)
    return accepted, refused


def effort_controller(node: rclpy.node.Node, _: int) -> dict[str, object]:
    """The commands heard in each case, each case lasting until the controller shows it took its states:
    good states' commands (the broadcaster's), a command from the sensor-data publisher's posture, and
    for a refused state its warning on /rosout, then a good state at the next posture until its command
    comes (whatever came before it in flight is the earlier postures')."""
    from rcl_interfaces.msg import Log

    commands, refused = forward_controller(node, len(JOINTS))
    logged: list[str] = []
    rosout = node.create_subscription(Log, "/rosout", lambda m: logged.append(m.msg), 100)
    broadcaster = node.create_publisher(JointState, "joint_states", qos_profile_system_default)
    sensor_data = node.create_publisher(JointState, "joint_states", qos_profile_sensor_data)
    while min(broadcaster.get_subscription_count(), sensor_data.get_subscription_count()) < 1 or (
        rosout.get_publisher_count() < 2  # this node's and the controller's
    ):
        rclpy.spin_once(node, timeout_sec=0.05)

    def good(k: int) -> JointState:
        q = EFFORT_POSTURES[k]
        msg = JointState(name=[JOINTS[j] for j in SHUFFLED], position=[q[j] for j in SHUFFLED])
        msg.velocity, msg.effort, msg.header.frame_id = [0.0] * 4, [math.nan] * 4, "base_link"
        return msg

    def until(pub: Any, msg: JointState, done: Callable[[], bool]) -> None:
        give_up = time.monotonic() + CASE_GIVE_UP_S
        while not done() and time.monotonic() < give_up:
            pub.publish(msg)
            rclpy.spin_once(node, timeout_sec=0.01)

    def new_command() -> bool:  # one no earlier case's state gives
        return any(not any(np.allclose(c, k, rtol=0, atol=1e-9) for k in known) for c in commands)

    def warned(words: str) -> Callable[[], bool]:
        return lambda: any(words in line for line in logged)

    q4 = EFFORT_POSTURES[4]
    bad_nan = JointState(name=JOINTS, position=[math.nan, *q4[1:]], velocity=[0.0] * 4)
    missing = JointState(name=JOINTS[:3], position=q4[:3], velocity=[0.0] * 3)
    seen: dict[str, list[list[float]]] = {}
    known: list[list[float]] = []
    until(broadcaster, good(0), lambda: len(commands) >= 5)
    seen["broadcaster"], known = list(commands), [commands[-1]] if commands else []
    for label, pub, bad, posture in (
        ("sensor_data", sensor_data, None, 1),
        ("nan", broadcaster, bad_nan, 2),
        ("missing", broadcaster, missing, 3),
    ):
        commands.clear()
        if bad is not None:
            until(pub, bad, warned("joint_states refused: non-finite" if label == "nan" else "missing joints"))
        until(pub, good(posture), new_command)
        seen[label] = list(commands)
        known += [c for c in commands if c not in known]
    infos = node.get_publishers_info_by_topic("/effort_controller/commands")
    reliability = [str(i.qos_profile.reliability.name) for i in infos]
    return {"commands": seen, "refused": refused, "publisher_reliability": reliability, "postures": EFFORT_POSTURES}


def _follow_run(
    node: rclpy.node.Node, on_state: Callable[[ControllerState], None], speaks: list[Any], rows: list[Any]
) -> None:
    """Follow controller_state with ``on_state`` (which appends to ``rows``) until the run has ended
    (3 s without a state). Once this script hears the controller and is heard by it (each of
    ``speaks`` matched), it subscribes to joint_states: a simulator with min_subscribers 2 steps only
    then, so the script cannot miss the run's start on a busy machine (it did once in CI)."""
    states = node.create_subscription(ControllerState, "controller_state", on_state, QoSProfile(depth=10000))
    while states.get_publisher_count() < 1 or any(pub.get_subscription_count() < 1 for pub in speaks):
        rclpy.spin_once(node, timeout_sec=0.05)
    node.create_subscription(JointState, "joint_states", lambda _msg: None, 10)
    deadline, quiet = time.monotonic() + 120, 0.0
    while time.monotonic() < deadline and quiet < 3.0:  # until the run has ended (3 s without a state)
        count = len(rows)
        rclpy.spin_once(node, timeout_sec=0.1)
        quiet = quiet + 0.1 if rows and len(rows) == count else 0.0


def target(node: rclpy.node.Node, t_pub: float, point: list[float], frame: str) -> dict[str, object]:
    """Three targets the controller must refuse, each once the one before is refused (the latest of a
    topic wins: sent at once, only the last would be taken), then ``point``."""
    pub = node.create_publisher(PointStamped, "hand_target", 10)
    refused: list[str] = []
    node.create_subscription(DiagnosticStatus, "hand_target/refused", lambda m: refused.append(m.message), 10)
    bad = [([0.0, 5.0, 5.0], "world"), (point, "base_link"), ([math.nan, 1.0, 0.6], "world")]
    rows: list[list[float]] = []
    sent: list[float] = []
    asked: list[int] = []

    def send(where: list[float], in_frame: str) -> None:
        msg = PointStamped()
        msg.header.frame_id = in_frame
        msg.point.x, msg.point.y, msg.point.z = where
        pub.publish(msg)

    def on_state(msg: ControllerState) -> None:
        t = _stamp(msg)
        d, a = msg.hand_desired, msg.hand_actual
        rows.append([t, d.x, d.y, d.z, a.x, a.y, a.z])
        if sent or t < t_pub or len(asked) > len(refused):
            return
        if len(asked) < len(bad):
            send(*bad[len(asked)])
            asked.append(1)
        else:
            send(point, frame)
            sent.append(t)

    _follow_run(node, on_state, [pub], rows)
    return {"sent_at": sent, "rows": rows, "refused": refused}


def _time_msg(t: float) -> object:
    from builtin_interfaces.msg import Time

    ns = round(t * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def path_and_brace(node: rclpy.node.Node, t_pub: float, poses: list[list[float]], dy: float) -> dict[str, object]:
    path_pub = node.create_publisher(Path, "hand_path", 10)
    brace_pub = node.create_publisher(PointStamped, "brace_target/elbow", 10)
    rows: list[list[float]] = []
    sent: list[list[float]] = []
    taken: dict[str, float] = {}  # the stamp of each echo: the state the controller took the target with [s]
    echoes = [
        node.create_subscription(kind, topic, lambda m, topic=topic: taken.setdefault(topic, _stamp(m)), 10)
        for kind, topic in ((Path, "hand_path/accepted"), (PointStamped, "brace_target/elbow/accepted"))
    ]

    def on_state(msg: ControllerState) -> None:
        d, a, bd, ba = msg.hand_desired, msg.hand_actual, msg.brace_desired[0], msg.brace_actual[0]
        rows.append([_stamp(msg), d.x, d.y, d.z, a.x, a.y, a.z, bd.x, bd.y, bd.z, ba.x, ba.y, ba.z])

    def send_once(msg: ControllerState) -> None:
        """On the newest state (a depth-1 subscription: never one of a backlog of rows, which a script slowed
        by a busy machine would reach late, sending late)."""
        t, bd = _stamp(msg), msg.brace_desired[0]
        if sent or t < t_pub or any(node.count_subscribers(echo.topic_name) < 2 for echo in echoes):
            return  # sent once the recorder's echo readers are known too (this script's are the other two)
        path = Path()
        path.header.frame_id = "world"
        for tp, x, y, z in poses:
            pose = PoseStamped()
            pose.header.frame_id, pose.header.stamp = "world", _time_msg(tp)
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
            pose.pose.orientation.w = 1.0
            path.poses.append(pose)
        brace = PointStamped()
        brace.header.frame_id = "world"
        brace.point.x, brace.point.y, brace.point.z = bd.x, bd.y + dy, bd.z
        path_pub.publish(path)
        brace_pub.publish(brace)
        sent.append([t, brace.point.x, brace.point.y, brace.point.z])

    node.create_subscription(ControllerState, "controller_state", send_once, QoSProfile(depth=1))
    while any(echo.get_publisher_count() < 1 for echo in echoes):  # heard before anything is sent
        rclpy.spin_once(node, timeout_sec=0.05)
    _follow_run(node, on_state, [path_pub, brace_pub], rows)
    return {"sent": sent, "rows": rows, "taken": taken}


TICK_ANSWER_WAIT_S = 1.0
"""[s] wall time an advancing /clock tick waits for its command before the next tick (lockstep: a loaded
machine slows the run, never merges two ticks into one timer call)."""


def sim_clock(node: rclpy.node.Node) -> dict[str, object]:
    from rosgraph_msgs.msg import Clock

    commands, _ = forward_controller(node, len(JOINTS))
    clock = node.create_publisher(Clock, "/clock", 10)
    states = node.create_publisher(JointState, "joint_states", qos_profile_system_default)
    while states.get_subscription_count() < 1 or clock.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    q = [-0.6283185307179586, -1.8849555921538759, 2.5132741228718345, -1.2566370614359172]
    counts = []
    for ticks, period, step in ((50, 0.02, 0.0), (50, 0.02, 0.01)):
        commands.clear()
        t = 5.0 if not counts else 5.0 + 0.0  # both phases start at 5 s
        for k in range(ticks):
            t_now = t + step * (k + 1) if step else t
            clock.publish(Clock(clock=_time_msg(t_now)))
            state = JointState(name=JOINTS, position=q, velocity=[0.0] * 4)
            state.header.stamp = _time_msg(t_now)
            states.publish(state)
            answered = len(commands) + 1
            end = time.monotonic() + (period if not step else TICK_ANSWER_WAIT_S)
            while time.monotonic() < end and not (step and len(commands) >= answered):
                rclpy.spin_once(node, timeout_sec=0.005)
        end = time.monotonic() + 0.2
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)
        counts.append(len(commands))
    return {"frozen": counts[0], "advancing": counts[1]}


def constant_effort(node: rclpy.node.Node, tau: list[float]) -> dict[str, object]:
    from rosgraph_msgs.msg import Clock

    from bracing_msgs.msg import MotorState

    deep = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
    clocks: list[float] = []
    efforts: list[list[float]] = []
    energy: list[list[float]] = []
    currents: list[list[float]] = []
    node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec + m.clock.nanosec * 1e-9), deep)
    node.create_subscription(JointState, "/robot_joint_states", lambda m: efforts.append([_stamp(m), *m.effort]), deep)
    node.create_subscription(
        MotorState, "motor_state", lambda m: energy.append([_stamp(m), m.energy_consumed, m.copper_loss]), deep
    )
    node.create_subscription(MotorState, "motor_state", lambda m: currents.append([_stamp(m), *m.current]), deep)
    pub = node.create_publisher(JointState, "/robot_joint_commands", RELIABLE_1)
    command = JointState(name=JOINTS, effort=tau)
    deadline, quiet = time.monotonic() + 120, 0.0
    while time.monotonic() < deadline and quiet < 2.0:  # until the run has ended (2 s without a clock)
        count = len(clocks)
        command.header.stamp = node.get_clock().now().to_msg()
        pub.publish(command)
        rclpy.spin_once(node, timeout_sec=0.01)
        quiet = quiet + 0.01 if clocks and len(clocks) == count else 0.0
    return {"clock": clocks, "efforts": efforts, "energy": energy, "current": currents}


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("ros2_control_peer")
    kind = sys.argv[1]
    if kind == "topic-system":
        out = topic_system(node, int(sys.argv[2]), json.loads(sys.argv[3]))
    elif kind == "sim-clock":
        out = sim_clock(node)
    elif kind == "constant-effort":
        out = constant_effort(node, json.loads(sys.argv[2]))
    elif kind == "path":
        out = path_and_brace(node, float(sys.argv[2]), json.loads(sys.argv[3]), float(sys.argv[4]))
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
