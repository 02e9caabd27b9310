"""Every link's collision shapes against every contact surface, at each state (``robot.collision_geometry``).

The engine measures them (coal, on the URDF's ``<collision>`` shapes: ``bracing_engine.Dynamics.measure_links``);
this module keeps what a run reports of it: per surface, the link deepest into it (or nearest it) at each state
(the simulator's ``link_penetration`` topic, one ``ContactState`` per surface named ``<link>@<contact>``), the
deepest each link went, and one warning per link deeper than ``robot.penetration_tolerance``.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

import bracing_engine as engine
from bracing_core.contact_roles import LINK_PENETRATION_TOPIC
from bracing_core.contacts import Surface
from bracing_core.dynamics import engine_surface
from bracing_core.types import Vector

if TYPE_CHECKING:  # the configuration's types only
    from bracing_core.config import Plant

TOPIC = LINK_PENETRATION_TOPIC
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
        self.tolerance = plant.config.penetration_tolerance
        owners = plant.distinct_surfaces()
        self.contacts = [owner.name for owner in owners]
        self.surfaces = [engine_surface(owner.surface) for owner in owners]
        self.engine = dynamics
        q0 = np.zeros(dynamics.nv)
        self.links: list[str] = list(dynamics.measure_links(q0, self.surfaces).links)  # the moving links with shapes
        # per link (plain lists: a handful of links, measured at every state, costs less without numpy)
        self._deepest = [0.0] * len(self.links)  # [m] the deepest it went (0: never inside)
        self._warned = [False] * len(self.links)

    @property
    def deepest(self) -> dict[str, float]:
        """{link: the deepest it went inside any surface so far [m] (0: never inside)}, per moving link with shapes."""
        return dict(zip(self.links, self._deepest, strict=True))

    def measure(self, q: Vector, t: float) -> tuple[list[LinkDepth], list[str]]:
        """The deepest link per surface at posture ``q`` (sim time ``t`` [s]), and the warnings it gives (a link
        deeper than the tolerance, once per link)."""
        count = len(self.links)
        if not count:
            return [], []
        measured = self.engine.measure_links(q, self.surfaces)
        distance = measured.distance.tolist()  # row s * count + k: surface s, link k
        reports, warnings = [], []
        for s, contact in enumerate(self.contacts):
            own = distance[s * count : (s + 1) * count]
            k = own.index(min(own))  # the link deepest into this surface (or nearest it)
            row, link = s * count + k, self.links[k]
            residual = own[k]
            reports.append(
                LinkDepth(
                    f"{link}@{contact}",
                    link,
                    measured.points[row],
                    measured.normals[row],
                    residual,
                    -residual > self.tolerance,
                )
            )
        for k in range(count):
            depth = -min(distance[k::count])
            if depth > self._deepest[k]:
                self._deepest[k] = depth
            if depth > self.tolerance and not self._warned[k]:
                self._warned[k] = True
                s = distance[k::count].index(-depth)
                warnings.append(penetration_warning(self.links[k], self.contacts[s], depth, t, self.tolerance))
        return reports, warnings


_DRIVE_ARRAYS = (
    "added_inertia",
    "damping",
    "torque_constant",
    "resistance",
    "inductance",
    "reflected_damping",
    "thermal_resistance",
    "heat_capacity",
)
"""engine.Drive's per-joint arrays."""


def bare_drive(joints: int) -> engine.Drive:
    """A drive that adds nothing to the links (torque input, no motor terms): the geometry's alone."""
    zeros = np.zeros(joints)
    arrays = dict.fromkeys(_DRIVE_ARRAYS, zeros)
    return engine.Drive(voltage=False, thermal=False, ambient=20.0, temperature_coefficient=0.0, **arrays)


def deepest_over_postures(
    description: str, joint_names: Sequence[str], positions: NDArray[np.float64], surfaces: Sequence[Surface]
) -> dict[str, float]:
    """{link: the deepest it went inside any of ``surfaces`` [m] (0: never)} over ``positions`` (rows: postures,
    columns: ``joint_names``), every moving link of the URDF ``description`` (meshes as file:// paths) with
    collision shapes, measured by the engine as the simulator measures them. ValueError if it cannot load them."""
    if not surfaces or not len(positions):
        return {}
    with tempfile.TemporaryDirectory(prefix="bracing-links-") as folder:
        urdf = Path(folder) / "robot.urdf"
        urdf.write_text(description, encoding="utf-8")
        robot = engine.Robot(urdf_path=str(urdf), gravity=np.zeros(3), collision_description=description)
        dynamics = engine.Dynamics(robot, bare_drive(len(joint_names)), [], 1e-4, 0.0)
    measured = [engine_surface(surface) for surface in surfaces]
    order = [list(joint_names).index(name) for name in dynamics.joint_names]
    links = list(dynamics.measure_links(np.zeros(len(joint_names)), measured).links)
    deepest = np.zeros(len(links))
    for q in np.asarray(positions, dtype=float)[:, order]:
        distance = dynamics.measure_links(q, measured).distance.reshape(len(measured), len(links))
        np.maximum(deepest, -distance.min(axis=0), out=deepest)
    return dict(zip(links, deepest.tolist(), strict=True))
