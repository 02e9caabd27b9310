"""What the simulator watches in its run and warns about (no ROS): one policy for the node and the
in-process rollout, so that a run says the same wherever it runs.

``RunWatch`` is fed what the simulator reports of each state (the rows of the ``contacts`` topic:
time, which contacts hold, normal forces, residuals) and the contact events, and answers with the
warnings each feed gives, once each (texts: ``checks``):

- at the start: ``project_initial_position`` moved a joint more than ``PROJECTION_MOVE_RAD``
  (``PROJECTION_MOVE_M`` for a prismatic joint);
- while it runs: a braced contact lets go of its surface after holding on it (once per contact); a
  braced contact that started off its surface first holds on it (once); a held contact drifts more
  than ``DRIFT_WARNING_M`` off its surface (once);
- at the end: a braced contact never held on its surface; a bilateral contact pulled (f_n below
  ``-PULL_FORCE_N``) in more than ``PULL_SHARE`` of the states;
- and the first report of each kind the node's log repeats (``once``: saturated commands, the
  watchdog), and real-time stepping slower than asked (``real_time``).

"Holds" is what the states say, not the events: a unilateral contact that touches down and lets go
again within one step (a bounce) never held, so it is neither reached nor let go (an arm
that touched down at 4.68 s and bounced: it was said to have let go, and never to have been reached).
The node says each warning in its log and on run_status (``bracing_ros.status``), whence the recorder
puts it in the bag and the summary takes it; ``rollout.run_recorded`` keeps them in the recording.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from bracing_core import checks

if TYPE_CHECKING:  # the configuration's types only
    from bracing_core.config import Plant, SimulatorConfig
    from bracing_core.simulator import Simulator
    from bracing_engine import ContactEvent

PULL_SHARE = 0.05
"""A bilateral contact that pulls in more than this share of a run's states is warned about (a few
steps of a transient are not a table that pulls)."""

PULL_FORCE_N = 1e-6
"""f_n below -this [N] is a pull (not rounding about zero)."""

PROJECTION_MOVE_RAD = 0.1
"""A revolute joint ``project_initial_position`` moved more than this [rad] is warned about."""

PROJECTION_MOVE_M = 0.01
"""A prismatic joint it moved more than this [m] is warned about."""

DRIFT_WARNING_M = 1e-7
"""A held contact further than this [m] off its surface: a warning that points at ``baumgarte``."""

_SAME_TIME_S = 1e-9  # an event at a state's time belongs to that state


class RunWatch:
    """The simulator's warnings about one run (see the module docstring). Build it at the start, before
    the first step (``at_start`` False: the simulator has stepped already, no start warnings)."""

    def __init__(self, plant: Plant, config: SimulatorConfig, simulator: Simulator, at_start: bool = True) -> None:
        contacts = plant.contact_set.contacts
        self.names = [c.name for c in contacts]
        braced = {c.name for c in plant.config.braced_contacts}
        self._braced = np.array([c.name in braced for c in contacts], dtype=bool)
        self._bilateral = np.flatnonzero([c.enforced and not c.unilateral for c in contacts])
        self._held = np.array(simulator.active, dtype=bool).reshape(len(contacts))  # at the last state seen
        self._reached = self._held & self._braced  # braced contacts that have held on their surfaces
        self._let_go = np.zeros(len(contacts), dtype=bool)
        self._force_gains = checks.force_feedback_gains(circuit_time_constant(plant), config.step)
        self._events: dict[tuple[str, str], list[float]] = {}  # (contact, release | touchdown) -> times
        self._states = 0
        self._pulls = np.zeros(self._bilateral.size, dtype=int)
        self._pull_sum = np.zeros(self._bilateral.size)
        self._pull_lowest = np.zeros(self._bilateral.size)
        self._pull_since = np.full(self._bilateral.size, np.nan)
        self._drifted = False
        self._kinds: set[str] = set()
        self._baumgarte = config.baumgarte
        self._start: list[str] = []
        if at_start and config.project_initial_position:
            given = plant.to_model_order(config.initial_position)
            warning = _projection(plant, given, simulator.position)
            self._start = [warning] if warning is not None else []
        self.warnings: list[str] = []  # every warning said so far, in order

    def _said(self, warnings: list[str]) -> list[str]:
        self.warnings += warnings
        return warnings

    def start(self) -> list[str]:
        """The start's warnings (the projection's); once."""
        out, self._start = self._start, []
        return self._said(out)

    def events(self, events: Sequence[ContactEvent]) -> None:
        """Contact events (releases and touchdowns give the warnings their times); before the states they lead to."""
        for event in events:
            kind = event.kind.name  # by name: the engine stays unloaded until a simulator brings it
            if kind in ("release", "touchdown"):
                self._events.setdefault((event.contact, kind), []).append(event.time)

    def _event_time(self, contact: str, kind: str, t: float) -> float:
        """The time of ``contact``'s last ``kind`` event at or before ``t`` [s] (``t`` itself if none)."""
        times = self._events.get((contact, kind), [])
        k = bisect.bisect_right(times, t + _SAME_TIME_S)
        return times[k - 1] if k else t

    def states(
        self, time: Sequence[float] | np.ndarray, active: ArrayLike, normal_force: ArrayLike, residual: ArrayLike
    ) -> list[str]:
        """The warnings of these states ((N,) times [s]; (N, p) which contacts hold, normal forces [N],
        residuals [m]; one state as (p,) rows too), in time order after those seen before."""
        times = np.atleast_1d(np.asarray(time, dtype=float))
        active = np.asarray(active, dtype=bool).reshape(times.size, -1)
        out = self._contact_changes(times, active) if (active != self._held).any() else []
        if self._bilateral.size:
            self._count_pulls(times, np.asarray(normal_force, dtype=float).reshape(times.size, -1))
        if not self._drifted:
            out += self._drift(times, active, np.asarray(residual, dtype=float).reshape(times.size, -1))
        self._states += times.size
        self._held = active[-1].copy()
        return self._said(out)

    def _contact_changes(self, times: np.ndarray, active: np.ndarray) -> list[str]:
        """A braced contact's first hold after a start off its surface, and its first let-go after holding."""
        out = []
        held = np.vstack([self._held, active])  # the state before these first
        for j in np.flatnonzero(self._braced & ~self._let_go):
            column, first = held[:, j], 0
            if not self._reached[j]:
                on = np.flatnonzero(column[1:])
                if not on.size:
                    continue
                first = int(on[0]) + 1
                self._reached[j] = True
                t = float(times[first - 1])
                out.append(checks.late_reach_warning(self.names[j], self._event_time(self.names[j], "touchdown", t)))
            drops = np.flatnonzero(column[first:-1] & ~column[first + 1 :])
            if drops.size:
                self._let_go[j] = True  # for good: said once, whatever it does next
                t = float(times[first + int(drops[0])])
                at = self._event_time(self.names[j], "release", t)
                out.append(checks.let_go_warning(self.names[j], at, self._force_gains))
        return out

    def _count_pulls(self, times: np.ndarray, normal_force: np.ndarray) -> None:
        force = normal_force[:, self._bilateral]
        pulling = force < -PULL_FORCE_N
        if not pulling.any():
            return
        counts = pulling.sum(axis=0)
        for k in np.flatnonzero(counts):
            if not self._pulls[k]:
                self._pull_since[k] = times[int(np.argmax(pulling[:, k]))]
            self._pull_lowest[k] = min(self._pull_lowest[k], float(np.min(force[:, k])))
            self._pull_sum[k] += float(np.sum(force[pulling[:, k], k]))
        self._pulls += counts

    def _drift(self, times: np.ndarray, active: np.ndarray, residual: np.ndarray) -> list[str]:
        off = np.where(active, np.abs(residual), 0.0)
        rows = np.flatnonzero(off.max(axis=1, initial=0.0) > DRIFT_WARNING_M)
        if not rows.size:
            return []
        self._drifted = True
        k = int(rows[0])
        j = int(np.argmax(off[k]))
        return [checks.drift_warning(self.names[j], float(off[k, j]), float(times[k]), self._baumgarte)]

    def finish(self) -> list[str]:
        """The end's warnings, once all the run's states are seen: braced contacts never reached, tables that pulled."""
        out = [checks.never_reached_warning(self.names[j]) for j in np.flatnonzero(self._braced & ~self._reached)]
        for k, j in enumerate(self._bilateral):
            if self._states and self._pulls[k] > PULL_SHARE * self._states:
                share, mean = self._pulls[k] / self._states, self._pull_sum[k] / self._pulls[k]
                since, lowest = float(self._pull_since[k]), float(self._pull_lowest[k])
                out.append(checks.pull_warning(self.names[j], share, since, lowest, mean))
        return self._said(out)

    def once(self, kind: str, message: str, t: float) -> list[str]:
        """The first report of ``kind`` (its log repeats them, rate-limited), at ``t`` [s]; nothing after."""
        if kind in self._kinds:
            return []
        self._kinds.add(kind)
        return self._said([checks.first_report_warning(message, t)])

    def real_time(self, achieved: float, requested: float) -> list[str]:
        """Real-time stepping at ``achieved`` x real time when ``requested`` was asked."""
        warning = checks.slow_real_time_warning(achieved, requested)
        return self._said([warning] if warning is not None else [])


def _projection(plant: Plant, given: np.ndarray, projected: np.ndarray) -> str | None:
    """The warning for joints ``project_initial_position`` moved far from ``given`` (model order), or None."""
    robot = plant.robot
    limits = np.where(robot.prismatic, PROJECTION_MOVE_M, PROJECTION_MOVE_RAD)
    far = np.flatnonzero(np.abs(projected - given) > limits)
    if not far.size:
        return None
    moves = [
        (
            robot.joint_names[k],
            float(given[k]),
            float(projected[k]),
            bool(robot.prismatic[k]),
            float(robot.lower_limits[k]),
            float(robot.upper_limits[k]),
        )
        for k in far
    ]
    return checks.projection_warning(moves, f"{PROJECTION_MOVE_RAD:g} rad ({PROJECTION_MOVE_M:g} m)")


def circuit_time_constant(plant: Plant) -> float:
    """[s] the slowest motor circuit's L / R (voltage input), 0 with torque input (no circuit)."""
    if plant.mode.value != "voltage":
        return 0.0
    motors = plant.motors
    return float(np.max(motors.inductance / motors.resistance)) if motors.inductance.size else 0.0
