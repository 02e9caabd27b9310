"""Re-exports for the three modules another change rewrites meanwhile (bracing_sim/node.py,
bracing_controller/node.py, bracing_bringup/mujoco_robot.py): the lead removes this module at merge,
importing from the modules below instead. Nothing else imports it."""

from bracing_ros.ack_window import AckWindow
from bracing_ros.matching import create_waking_publisher, wait_until
from bracing_ros.node_main import EXIT_DIVERGED, run
from bracing_ros.qos import STREAM_QOS, SUBSCRIBE_QOS
from bracing_ros.rate_log import RateLimitedLog
from bracing_ros.raw_messages import read_joint_state, read_motor_command
from bracing_ros.waiter import SubscriptionWaiter

__all__ = [
    "EXIT_DIVERGED",
    "STREAM_QOS",
    "SUBSCRIBE_QOS",
    "AckWindow",
    "RateLimitedLog",
    "SubscriptionWaiter",
    "create_waking_publisher",
    "read_joint_state",
    "read_motor_command",
    "run",
    "wait_until",
]
