"""The QoS table: every profile a node publishes or subscribes with, one per topic role.

Every ``create_publisher``/``create_subscription`` in the nodes takes its profile from here
(test_qos_table checks it). All keep the last ``depth`` samples; what differs is how many, whether
delivery is reliable and whether a late subscriber still gets what was sent before it matched.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_system_default

RELIABLE = ReliabilityPolicy.RELIABLE
BEST_EFFORT = ReliabilityPolicy.BEST_EFFORT
LATCHED = DurabilityPolicy.TRANSIENT_LOCAL
VOLATILE = DurabilityPolicy.VOLATILE


def _keep_last(depth: int, reliability: ReliabilityPolicy, durability: DurabilityPolicy) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability, durability=durability)


# Reliable, transient-local and deep: a subscriber that discovers a publisher late (the recorder
# on a busy machine) still receives what was sent before the match. A KEEP_LAST writer drops its
# oldest sample when the history is full, acknowledged or not; AckWindow (every depth / 2
# messages) makes sure no unacknowledged sample is ever that old.
STREAM_QOS = _keep_last(10000, RELIABLE, LATCHED)
"""The per-state topics the simulators publish (joint_states, contacts, wrenches, /clock, ...)."""

# The nodes' own subscriptions are volatile: a node (re)started mid-run must answer the
# current state, not replay history. (A volatile subscription matches the publishers above.)
SUBSCRIBE_QOS = _keep_last(2000, RELIABLE, VOLATILE)
"""The simulator's and the controller's subscriptions to each other's per-state topics."""

DESCRIPTION_QOS = _keep_last(1, RELIABLE, LATCHED)
"""robot_description as robot_state_publisher offers it: one message, kept for late subscribers."""

COMMAND_QOS = _keep_last(10, RELIABLE, VOLATILE)
"""Effort commands, both ways of ros2_control. ros-controls/ros2_controllers
forward_command_controller/src/forward_controllers_base.cpp (which effort_controllers/
JointGroupEffortController derives from on Jazzy; on Rolling a ForwardCommandController with
interface_name effort) subscribes ``~/commands`` with SystemDefaultsQoS: the RMW's own choice
(rmw_fastrtps_cpp here: a best-effort, volatile reader). A reliable, volatile publisher matches it
whatever it resolves to; the MuJoCo robot's reliable ``~/commands`` subscription keeps every command.
ros-controls/topic_based_hardware_interfaces' joint_state_topic_hardware_interface.cpp sends its
robot_joint_commands with rclcpp::QoS(1) (reliable, volatile, depth 1) and reads robot_joint_states
with SensorDataQoS (best effort, the latest kept): a reliable subscription matches its publisher, a
reliable publisher its best-effort reader."""

CMD_VEL_QOS = qos_profile_system_default
"""cmd_vel as diff_drive_controller subscribes it (SystemDefaultsQoS: the RMW's own choice), so that whatever
a teleop or a navigation stack publishes with matches."""

JOINT_STATE_QOS = _keep_last(10, BEST_EFFORT, VOLATILE)
"""A ros2_control robot's joint_states, best effort: matches joint_state_broadcaster's publisher
(ros2_controllers joint_state_broadcaster.cpp: SystemDefaultsQoS, under rmw_fastrtps_cpp a reliable,
transient-local writer) and a SensorDataQoS publisher alike; the latest counts."""

TARGET_QOS = _keep_last(1, RELIABLE, VOLATILE)
"""Targets (the latest wins: an older one waiting in the reader would be superseded anyway). What a
script, RViz or MoveIt publishes by default (reliable); a transient-local publisher matches it too."""

ECHO_QOS = _keep_last(100, RELIABLE, VOLATILE)
"""The controller's echo of each target accepted or refused: at most one per topic per state, so a
recorder that lags a little still gets each."""

STATUS_QOS = _keep_last(100, RELIABLE, LATCHED)
"""run_status: a run's few events and warnings and its latest progress, kept for a late subscriber."""

RECORD_BATCH_QOS = _keep_last(100, RELIABLE, LATCHED)
"""record_batch: batches of ~100 states (~100 kB each) kept for a late recorder (AckWindow every 50);
transient-local is what the recorder's reader matches."""

RECORD_QOS = _keep_last(100000, RELIABLE, LATCHED)
"""The recorder's subscriptions: reliable, deep and transient-local, so that nothing is lost in lockstep
runs: a publisher that starts before the recorder has discovered it still delivers its first messages.
(It matches the nodes' transient-local publishers; a volatile publisher is not recorded.)"""

PARAMETER_EVENTS_QOS = _keep_last(1000, RELIABLE, VOLATILE)
"""rclpy's own for /parameter_events: its publishers are volatile, which a transient-local
subscription would not match. The recorder's subscriptions to the targets too (a script's, RViz's,
MoveIt's publishers are volatile)."""

VIEW_QOS = _keep_last(100, BEST_EFFORT, VOLATILE)
"""The viewer's live subscriptions: best effort (it draws the latest, it must never slow a run down)."""
