"""effort_forward's ``state_timeout``: no command from a state that old, zero efforts instead; no ROS.

Times are the node's clock [ns] (``use_sim_time``: /clock) when each joint_states arrived. Why zero
and not silence: ros2_controllers' forward_command_controller (forward_controllers_base.cpp, jazzy)
writes the last command it took to its interfaces on every update, with no timeout, and drops a
message holding a NaN; silence would leave the robot under the last efforts for good, computed from a
state nobody sees any more. Zero is what the JointGroupEffortController itself commands when it stops
(its on_deactivate sets every effort interface to 0.0, "stop all joints"), and what our simulator's
command watchdog does. The zeros go out at the control rate while the state is stale (the forward
controller's SystemDefaultsQoS reader may be best effort, and one that is activated later still gets
them), and only after a state has been answered (before that the forward controller holds NaN: it
writes nothing).

A clock that jumps back (a reset, ROS time-jump semantics: ``bracing_core.sim_clock``) makes the held
state stale at once: it arrived after the new time, on the timeline before the reset.
"""

from __future__ import annotations

from bracing_core.node_log import NodeLog
from bracing_core.sim_clock import seconds
from bracing_core.stamps import NS_PER_S


class StateFreshness:
    """Whether the latest joint_states may be answered, and whether zero efforts are due (``timeout_s`` 0: off)."""

    def __init__(self, timeout_s: float, log: NodeLog) -> None:
        self.timeout_ns = round(timeout_s * NS_PER_S)
        self._log = log
        self.received_ns: int | None = None  # when the latest state arrived
        self.answered_ns: int | None = None  # when the latest state answered arrived
        self.stale = False

    @property
    def enabled(self) -> bool:
        return self.timeout_ns > 0

    def received(self, now_ns: int) -> None:
        """A joint_states arrived at ``now_ns``."""
        self.received_ns = now_ns

    def answered(self) -> None:
        """The latest state was answered: a command was computed from it."""
        self.answered_ns = self.received_ns

    def usable(self, now_ns: int) -> bool:
        """Whether the latest state may still be answered at ``now_ns`` (always, when off)."""
        return not self.enabled or self.received_ns is None or self._fresh(self.received_ns, now_ns)

    def zero_due(self, now_ns: int) -> bool:
        """Whether zero efforts go out at ``now_ns``: none answered within state_timeout (once one was).
        Says when the state goes stale and when states are answered again (rate-limited)."""
        if not self.enabled or self.answered_ns is None:
            return False
        stale = not self._fresh(self.answered_ns, now_ns)
        if stale and not self.stale:
            self._log.limited("warning", "state-stale", self._stale_text(self.answered_ns, now_ns))
        elif self.stale and not stale:
            self._log.limited("info", "state-resumed", "joint_states answered again: efforts from the law resume")
        self.stale = stale
        return stale

    def _fresh(self, arrived_ns: int, now_ns: int) -> bool:
        return 0 <= now_ns - arrived_ns <= self.timeout_ns

    def _stale_text(self, arrived_ns: int, now_ns: int) -> str:
        limit = f"state_timeout {self.timeout_ns / NS_PER_S:g} s"
        if now_ns < arrived_ns:
            why = "the clock jumped back past the last state answered"
        else:
            why = f"no state answered for {seconds(now_ns - arrived_ns)} s"
        return f"joint_states stale ({why}; {limit}): sending zero efforts until a state is answered again"
