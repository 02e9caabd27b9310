"""What the controller measures besides the joints, and which measurement a state is answered with (no ROS).

Force feedback reads each fed-back contact's force (``contact_wrench/<name>``), thermal compensation the
windings' temperatures (``motor_state``). The simulator reports a step after it has published the state
the step led to, so the controller answering state k + 1 waits, briefly, for the reports of step k (those
stamped with the state it answered last): what the in-process rollout feeds the law, so that a lockstep
pair and a rollout run the same loop. The first state has no such report: the law starts without one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bracing_core.kinematics import WORLD_FRAME as WORLD
from bracing_core.law import DecoupledController
from bracing_core.message_limits import shorten
from bracing_core.types import Vector


class Measurements:
    """The latest measurement per source (a contact's force, the temperatures) with its stamp [ns]."""

    def __init__(self, forces: Sequence[str], temperature: bool, topics: Sequence[str] = ()) -> None:
        self.forces = list(forces)  # the braced contacts whose force is fed back, in the law's brace order
        self.topics = list(topics) or [f"contact_wrench/{name}" for name in forces]  # where each force comes from
        self.temperature = temperature
        self._force: dict[str, tuple[int, Vector]] = {}
        self._temperature: tuple[int, Vector] | None = None

    @classmethod
    def for_law(cls, law: DecoupledController) -> Measurements | None:
        """What ``law`` reads (None: nothing; the paper's law)."""
        if not (law.uses_force_feedback or law.uses_temperature):
            return None
        braced = law.config.shared.braced_contacts if law.uses_force_feedback else ()
        return cls([c.name for c in braced], law.uses_temperature, [c.feedback_topic for c in braced])

    def take_force(self, contact: str, stamp_ns: int, force: Vector, frame: str = WORLD) -> str | None:
        """Keep a contact's measured force [N] on the robot, in ``frame`` (world axes only); why not, if it
        is refused."""
        topic = self.topics[self.forces.index(contact)] if contact in self.forces else contact
        value = np.asarray(force, dtype=float)
        if value.shape != (3,) or not np.isfinite(value).all():
            return f"{topic}: force {value.tolist()} is not 3 finite numbers"
        if frame not in (WORLD, ""):
            return (
                f"{topic}: frame_id {shorten(frame)!r}: force feedback takes forces in world axes (frame_id {WORLD!r})"
            )
        if contact in self.forces:
            self._force[contact] = (stamp_ns, value)
        return None

    def take_temperature(self, stamp_ns: int, temperature: Vector, joints: int) -> str | None:
        """Keep the windings' temperatures [degC] (model order); why not, if they are refused."""
        if len(temperature) != joints:  # before any work per element: the message may hold any number
            return f"motor_state: {len(temperature)} temperatures, not {joints} (one per joint)"
        value = np.asarray(temperature, dtype=float)
        if not np.isfinite(value).all():
            return f"motor_state: temperature {value.tolist()} is not {joints} finite numbers"
        self._temperature = (stamp_ns, value)
        return None

    def ready(self, since_ns: int | None) -> bool:
        """Every source has a measurement stamped ``since_ns`` or later (None: the first state, nothing to wait for)."""
        return since_ns is None or not self.missing(since_ns)

    def missing(self, since_ns: int) -> list[str]:
        """The sources without a measurement stamped ``since_ns`` or later."""
        out = [
            t
            for c, t in zip(self.forces, self.topics, strict=True)
            if c not in self._force or self._force[c][0] < since_ns
        ]
        if self.temperature and (self._temperature is None or self._temperature[0] < since_ns):
            out.append("motor_state")
        return out

    def apply(self, law: DecoupledController) -> None:
        """Give ``law`` the latest of each measurement (none yet: it keeps what it had)."""
        for j, contact in enumerate(self.forces):
            if contact in self._force:
                law.measure_force(j, self._force[contact][1])
        if self._temperature is not None:
            law.measure_temperature(self._temperature[1])
