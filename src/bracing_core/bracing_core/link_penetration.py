"""Every link's collision shapes against every contact surface, at each state (``robot.collision_geometry``).

The engine measures them (coal, on the URDF's ``<collision>`` shapes: ``bracing_engine.Dynamics.measure_links``);
this module keeps what a run reports of it: per surface, the link deepest into it (or nearest it) at each state
(the simulator's ``link_penetration`` topic, one ``ContactState`` per surface named ``<link>@<contact>``), the
deepest each link went, and one warning per link deeper than ``robot.penetration_tolerance``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

import bracing_engine as engine
from bracing_core.dynamics import engine_surface
from bracing_core.types import Vector

if TYPE_CHECKING:  # the configuration's types only
    from bracing_core.config import Plant

TOPIC = "link_penetration"
"""The simulator's per-state topic (bracing_msgs/Contacts) with robot.collision_geometry."""


@dataclass(frozen=True)
class LinkDepth:
    """The link deepest into (or nearest) one contact surface at one state: a ``ContactState`` of the topic."""

    name: str  # <link>@<contact>
    link: str  # the ContactState's frame
    position: Vector  # the link's point deepest in / nearest the surface, world [m]
    normal: Vector  # the surface's normal there
    residual: float  # [m] signed distance of that point from the surface (< 0: inside)
    active: bool  # deeper than robot.penetration_tolerance


def penetration_warning(link: str, contact: str, depth: float, t: float, tolerance: float) -> str:
    """The warning for a link found ``depth`` [m] inside the surface of ``contact`` at sim time ``t`` [s]."""
    return (
        f"link {link!r} is {depth:.4g} m inside the surface of contact {contact!r} at t = {t:.3f} s (deeper than "
        f"robot.penetration_tolerance {tolerance:g} m): its collision shapes cross the surface. Brace it at its "
        f"surface with contacts.<name>.point: geometry, or keep it out with robot.collision_links"
    )


class LinkPenetration:
    """What a run says of its links against the surfaces (module docstring), fed each state's q."""

    def __init__(self, plant: Plant, dynamics: engine.Dynamics) -> None:
        config = plant.config
        self.tolerance = config.penetration_tolerance
        owners = plant.distinct_surfaces()
        self.contacts = [owner.name for owner in owners]
        self.surfaces = [engine_surface(owner.surface) for owner in owners]
        self.engine = dynamics
        self.deepest: dict[str, float] = {}  # [m] per link with shapes: the deepest it went (0: never inside)
        self._warned: set[str] = set()

    def measure(self, q: Vector, t: float) -> tuple[list[LinkDepth], list[str]]:
        """The deepest link per surface at posture ``q`` (sim time ``t`` [s]), and the warnings it gives (a link
        deeper than the tolerance, once per link)."""
        measured = self.engine.measure_links(np.asarray(q, dtype=float), self.surfaces)
        links = list(measured.links)
        count = len(links)
        distance = np.asarray(measured.distance).reshape(len(self.surfaces), count)
        for k, link in enumerate(links):
            self.deepest[link] = max(self.deepest.get(link, 0.0), -float(np.min(distance[:, k], initial=0.0)))
        reports, warnings = [], []
        for s, contact in enumerate(self.contacts):
            if not count:
                break
            k = int(np.argmin(distance[s]))
            row = s * count + k
            residual = float(distance[s, k])
            reports.append(
                LinkDepth(
                    f"{links[k]}@{contact}",
                    links[k],
                    np.array(measured.points[row]),
                    np.array(measured.normals[row]),
                    residual,
                    -residual > self.tolerance,
                )
            )
            for j, link in enumerate(links):
                depth = -float(distance[s, j])
                if depth > self.tolerance and link not in self._warned:
                    self._warned.add(link)
                    warnings.append(penetration_warning(link, contact, depth, t, self.tolerance))
        return reports, warnings
