"""Each contact's role in a run, from its name alone (no pinocchio, no rclpy: the analysis reads bags with it).

A run's ``contacts`` topic holds two kinds of contact:

- ``braced``: a contact the scenario names (``contacts.<name>``): a braced point, or an obstacle that
  only pushes (whether the controller keeps a force on it, summary.json's per-contact ``braced`` says);
- ``kept_out``: a frame of ``robot.collision_frames`` or a link of ``robot.collision_links`` kept on
  the free side of a contact's surface, named ``<frame or link>@<contact>`` (``kept_out_name``).

A contact name cannot hold ``@`` (a ROS parameter name has none), so the name says the role. The
summaries, the plots, the report, bracing-view and the animation all ask ``role`` here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TypeVar

LINK_PENETRATION_TOPIC = "link_penetration"
"""bracing_msgs/Contacts the simulator publishes at every state with robot.collision_geometry: one
ContactState per surface, for the link deepest in or nearest to it (name ``<link>@<contact>``, frame the
link, active = deeper than robot.penetration_tolerance, position its point deepest in [m, world], normal
the surface's, residual the signed distance [m], negative inside). Not a contact: it has no role."""

BRACED = "braced"
KEPT_OUT = "kept_out"
ROLES = (BRACED, KEPT_OUT)
SEPARATOR = "@"

_T = TypeVar("_T")


def kept_out_name(kept: str, contact: str) -> str:
    """The pseudo-contact of frame or link ``kept`` on the surface of ``contact``: ``kept@contact``."""
    return f"{kept}{SEPARATOR}{contact}"


def role(name: str) -> str:
    """``kept_out`` for a ``<frame or link>@<contact>`` name, ``braced`` for a scenario's contact."""
    return KEPT_OUT if SEPARATOR in name else BRACED


def surface_owner(name: str) -> str:
    """The scenario contact whose surface ``name`` is on: itself, or the part after ``@``."""
    return name.rsplit(SEPARATOR, 1)[-1]


def kept_part(name: str) -> str:
    """The frame or link of a ``kept_out`` name (the part before ``@``); the name itself otherwise."""
    return name.rsplit(SEPARATOR, 1)[0]


def by_role(items: Mapping[str, _T], wanted: str) -> dict[str, _T]:
    """The entries of ``items`` (keyed by contact name) whose role is ``wanted``, in their order."""
    return {name: item for name, item in items.items() if role(name) == wanted}


def surface_names(names: Iterable[str]) -> list[str]:
    """The distinct surfaces among these contacts (each once, named by its owner), first seen first."""
    return list(dict.fromkeys(surface_owner(name) for name in names))
