"""What a node does with each /clock it is given (``use_sim_time``): the checks, no ROS.

rclpy's own TimeSource turns each message into an rclpy Time at once, and Time refuses a negative
time with a ValueError that escapes the executor's spin: one ``sec = -1`` ended the node. Here each
/clock is checked first (``bracing_ros.sim_clock`` drives the node's clock with what this takes):

- negative (``sec < 0``), or malformed (``nanosec`` >= 10^9, outside builtin_interfaces/Time's range):
  refused with a rate-limited warning; the node's clock stays where it was.
- back (earlier than the last one taken): taken, and reported. ROS time-jump semantics: a simulator
  that resets, or a bag played again, sends its clock back, and rcl restarts the node's timers from
  the new time (rcl's timer jump handler: the next call one period after it, not a wait for the old
  time to come round again); a state received before the jump is stale after it
  (``bracing_core.state_freshness``).
- far ahead (more than ``AHEAD_REPORT_S`` past the last one): taken, and reported. A forward jump is
  time passing (a bag played from a later point, a simulator fast-forwarded); rcl fires a timer once
  for it and skips the periods jumped over (``rcl_timer_call``), so there is no burst of callbacks.
  Refusing it would stop the clock for good after a legitimate jump (every later /clock is as far
  ahead of the last one taken), and a stray one costs little: the clock comes back with the next
  true /clock (a jump back), and the controller's law takes its time from the state's stamp, not
  from this clock.
"""

from __future__ import annotations

from bracing_core.node_log import NodeLog
from bracing_core.stamps import NS_PER_S, ns_of

AHEAD_REPORT_S = 1.0
"""[s] A /clock this far past the last one is reported (still taken): a thousand of our 1 ms steps,
far more than any simulator's or bag player's tick, far less than a stray timestamp's error."""


class ClockGuard:
    """Each /clock checked before it sets the node's clock: ``take`` says what time to set, if any."""

    def __init__(self, log: NodeLog) -> None:
        self._log = log
        self.last_ns: int | None = None  # the last /clock taken

    def take(self, sec: int, nanosec: int) -> int | None:
        """The time [ns] to set the node's clock to, or None: the message is refused (reported)."""
        if sec < 0:
            self._log.limited("warning", "clock-negative", f"/clock refused: negative time (sec {sec}); {self._now()}")
            return None
        if not 0 <= nanosec < NS_PER_S:
            self._log.limited(
                "warning", "clock-malformed", f"/clock refused: nanosec {nanosec} outside [0, 10^9); {self._now()}"
            )
            return None
        t_ns = ns_of(sec, nanosec)
        last = self.last_ns
        self.last_ns = t_ns
        if last is not None and t_ns < last:
            self._log.limited(
                "warning",
                "clock-back",
                f"/clock jumped back from {seconds(last)} s to {seconds(t_ns)} s: taken as a reset "
                "(ROS time-jump semantics: timers restart from it)",
            )
        elif last is not None and t_ns - last > AHEAD_REPORT_S * NS_PER_S:
            self._log.limited(
                "warning",
                "clock-ahead",
                f"/clock jumped {seconds(t_ns - last)} s ahead, from {seconds(last)} s to {seconds(t_ns)} s: taken "
                "(a timer fires once for it)",
            )
        return t_ns

    def _now(self) -> str:
        """The clock as a refusal says it (built only for a refusal, not for every /clock)."""
        return "clock none yet" if self.last_ns is None else f"clock {seconds(self.last_ns)} s"


def seconds(t_ns: int) -> str:
    """``t_ns`` [ns] as seconds with every nanosecond (a float would round a far-ahead time)."""
    sign = "-" if t_ns < 0 else ""
    return f"{sign}{abs(t_ns) // NS_PER_S}.{abs(t_ns) % NS_PER_S:09d}"
