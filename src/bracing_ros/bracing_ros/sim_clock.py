"""A node's /clock (``use_sim_time``) checked before it sets the node's clock (``guard_clock``).

rclpy's TimeSource subscribes /clock for a node with ``use_sim_time`` and builds an rclpy Time from
each message in its callback; a negative time raises ValueError there, out of the executor's spin, and
the node exits. ``guard_clock`` puts a TimeSource in its place that asks ``bracing_core.sim_clock``'s
``ClockGuard`` first: a bad /clock is refused with a rate-limited report, jumps are taken with ROS's
time-jump semantics (rcl's jump handlers reset the node's timers), and the node goes on.
"""

from __future__ import annotations

from rclpy.clock import ROSClock
from rclpy.node import Node
from rclpy.time_source import TimeSource
from rosgraph_msgs.msg import Clock

from bracing_core.node_log import NodeLog
from bracing_core.sim_clock import ClockGuard


class GuardedTimeSource(TimeSource):
    """rclpy's TimeSource (the same subscription, parameter and clocks) with each /clock checked first."""

    def __init__(self, guard: ClockGuard, node: Node) -> None:
        self.guard = guard
        super().__init__(node=node)

    def clock_callback(self, msg: Clock) -> None:
        if self.guard.take(int(msg.clock.sec), int(msg.clock.nanosec)) is not None:  # then rclpy's cannot raise
            super().clock_callback(msg)


def guard_clock(node: Node, log: NodeLog) -> GuardedTimeSource:
    """Replace ``node``'s TimeSource by a ``GuardedTimeSource`` (call it in the node's ``__init__``,
    before anything else sets the node's clock: it starts from 0, active as ``use_sim_time`` says).

    rclpy makes the TimeSource in Node's constructor (``Node._time_source``) with no hook to choose
    another, so the old one is detached here (its /clock subscription destroyed; its parameter
    callback stays registered but, detached, subscribes nothing and sets the clock's activity as
    the new one does).
    """
    clock = node.get_clock()
    assert isinstance(clock, ROSClock)  # a node's clock is
    old: TimeSource = node._time_source  # rclpy has no public way to swap it
    old.detach_node()
    guarded = GuardedTimeSource(ClockGuard(log), node)
    guarded.attach_clock(clock)
    node._time_source = guarded
    return guarded
