"""What is kept out of the surfaces (robot.collision_frames, robot.collision_links) and the URDF's collision shapes
as the engine takes them (robot.collision_geometry, robot.collision_links, contacts.<name>.point: geometry): the
text it loads them from, and the refusals, said before the run starts in the configuration's words."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol

from bracing_core.contact_config import ContactConfig
from bracing_core.contact_roles import kept_out_name
from bracing_core.contacts import Contact, Plane, Sphere, Surface
from bracing_core.meshes import resolved_description
from bracing_core.params import ConfigError


class SharedConfig(Protocol):
    """What these rules read of a ``config.SharedConfig``."""

    @property
    def urdf(self) -> Path: ...
    @property
    def package_paths(self) -> tuple[str, ...]: ...
    @property
    def contacts(self) -> Sequence[ContactConfig]: ...
    @property
    def collision_frames(self) -> tuple[str, ...]: ...
    @property
    def collision_links(self) -> tuple[str, ...]: ...
    @property
    def collision_geometry(self) -> bool: ...


def kept_out_contacts(
    config: SharedConfig,
    surfaces: Sequence[ContactConfig],
    surface_key: Callable[[Surface], tuple[Any, ...]],
    enforced: bool,
) -> list[Contact]:
    """Each collision frame, and each collision link (its shapes' point nearest the surface), against each distinct
    surface (``surfaces``: the first contact on each): unilateral, named <frame>@<contact> (<link>@<contact>), with
    that contact's friction; none where a configured contact already holds that frame on that surface."""
    taken = {(contact.frame, surface_key(contact.surface)) for contact in config.contacts}
    kept_out = [(frame, "frame") for frame in config.collision_frames]
    kept_out += [(link, "geometry") for link in config.collision_links]
    out = []
    for frame, point in kept_out:
        for owner in surfaces:
            if (frame, surface_key(owner.surface)) not in taken:
                name = kept_out_name(frame, owner.name)
                out.append(
                    Contact(name, frame, owner.surface, owner.friction, True, enforced, owner.friction_model, point)
                )
    return out


def check_measurable(config: SharedConfig) -> None:
    """Every surface the links' shapes are measured against is one coal measures them against (a plane or the
    outside of a sphere): a ConfigError naming the contact and what to set otherwise."""
    for contact in config.contacts:
        surface = contact.surface
        measured = config.collision_geometry or config.collision_links or contact.point == "geometry"
        if measured and not (isinstance(surface, Plane) or (isinstance(surface, Sphere) and not surface.inside)):
            kind = "the inside of a sphere" if isinstance(surface, Sphere) else f"a {surface.kind}"
            raise ConfigError(
                f"contacts.{contact.name}.surface: {kind} cannot be measured against the links' collision shapes "
                "(coal measures them against a plane or the outside of a sphere): remove robot.collision_geometry, "
                "robot.collision_links and point: geometry, or make it a plane"
            )


def collision_description(config: SharedConfig) -> str:
    """The URDF's own text (every joint, as the engine loads it) with each mesh found as a file:// path (as
    robot_description has them); a mesh not found stays as written, and the engine's error names it."""
    here = config.urdf.parent
    dirs = [here / Path(entry).expanduser() for entry in config.package_paths]
    try:
        text = config.urdf.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"robot.urdf: cannot read {config.urdf}: {exc}") from None
    return resolved_description(text, dirs, here)[0]


def shape_error(config: SharedConfig, text: str) -> str:
    """The engine's refusal of the shapes (``text``) in the configuration's words: a kept-out link's contact
    names robot.collision_links."""
    for link in config.collision_links:
        if f"frame {link} has no collision shapes" in text:
            return (
                f"robot.collision_links: link {link!r} has no <collision> shapes in the URDF ({config.urdf}): give it "
                "one, or remove it from robot.collision_links"
            )
    return text
