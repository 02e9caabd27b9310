"""The nodes' QoS profiles: what they publish (kept for late subscribers) and what they subscribe to."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Reliable, transient-local and deep: a subscriber that discovers a publisher late (the recorder
# on a busy machine) still receives what was sent before the match. A KEEP_LAST writer drops its
# oldest sample when the history is full, acknowledged or not; AckWindow (every depth / 2
# messages) makes sure no unacknowledged sample is ever that old.
STREAM_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# The nodes' own subscriptions are volatile: a node (re)started mid-run must answer the
# current state, not replay history. (A volatile subscription matches the publishers above.)
SUBSCRIBE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=2000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
