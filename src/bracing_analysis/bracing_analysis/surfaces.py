"""The contact surfaces of a run, as the recorder's markers and the report's animation draw them
(no rclpy, no pinocchio).

The bag's messages say where each contact point is and its surface normal there, which pins a
plane down but not a sphere or a cylinder (their centre and radius). The recorder reads the
surfaces from the scenario files the nodes got (``--scenario``), draws them (``scene``) and keeps
them in the bag's metadata (``custom_data``, key ``SURFACES_KEY``, JSON), where ``bag.read_series``
finds them for the animation. A bag without them is drawn as before: each surface as its tangent plane.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bracing_core import schema
from bracing_core.contact_roles import surface_owner
from bracing_core.overrides import SIMULATOR
from bracing_core.rcl_yaml import load_params_file

SCENARIO_KEY = "bracing.scenario"
"""Bag metadata (custom_data): the scenario's name, its file's stem (``paper_4link``)."""
SURFACES_KEY = "bracing.surfaces"
"""Bag metadata (custom_data): every contact's surface, JSON (``to_json``)."""

CURVED = ("sphere", "cylinder")


@dataclass(frozen=True)
class Shape:
    """One contact's surface: ``kind`` and the geometry of that kind (schema.CONTACT's fields)."""

    kind: str  # plane | sphere | cylinder
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)  # plane: unit normal
    offset: float = 0.0  # plane: n . r = offset [m]
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)  # sphere [m]
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)  # cylinder: a point of its axis [m]
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)  # cylinder: unit axis
    radius: float = 0.0  # sphere, cylinder [m]
    inside: bool = False  # sphere, cylinder: the frame stays inside

    @property
    def curved(self) -> bool:
        return self.kind in CURVED


def _unit(values: Sequence[float] | None, default: tuple[float, float, float]) -> tuple[float, float, float]:
    vector = np.asarray(values if values else default, dtype=float)
    norm = float(np.linalg.norm(vector))
    x, y, z = (vector / norm if norm > 0.0 else np.asarray(default)).tolist()
    return (x, y, z)


def _xyz(values: Sequence[float] | None) -> tuple[float, float, float]:
    x, y, z = (list(values) if values else [0.0, 0.0, 0.0])[:3]
    return (float(x), float(y), float(z))


def shape_from_values(own: schema.Section) -> Shape:
    """The shape of one contact from its typed schema values (``schema.read``'s ``contacts[name]``)."""
    return Shape(
        kind=str(own.surface or "plane"),
        normal=_unit(own.normal, (0.0, 0.0, 1.0)),
        offset=float(own.offset or 0.0),
        center=_xyz(own.center),
        point=_xyz(None if isinstance(own.point, str) else own.point),  # a word: a plane's or sphere's
        axis=_unit(own.axis, (0.0, 0.0, 1.0)),
        radius=float(own.radius or 0.0),
        inside=bool(own.inside),
    )


def read_scenario(files: Sequence[str | Path]) -> dict[str, Shape]:
    """Every contact's surface from the simulator's parameters in these params files (later files
    win, as with several ``--params-file``). Raises ConfigError for a file the nodes would refuse."""
    params: dict[str, Any] = {}
    for file in files:
        params.update(load_params_file(file, SIMULATOR))
    return shapes_from_values(schema.read("simulator", params))


def shapes_from_values(values: schema.Values) -> dict[str, Shape]:
    """Every contact's surface from the simulator's typed values (``schema.read``)."""
    return {name: shape_from_values(own) for name, own in values.contacts.items()}


def add_params_file_option(parser: argparse.ArgumentParser, text: str) -> None:
    """``--params-file FILE`` (repeatable, into ``params_files``): the files :func:`read_scenario` reads."""
    parser.add_argument("--params-file", dest="params_files", action="append", default=[], metavar="FILE", help=text)


def shape_of(surfaces: Mapping[str, Shape], contact: str) -> Shape | None:
    """The surface of ``contact``; a collision frame's contact (``frame@owner``) is on its owner's."""
    return surfaces.get(contact) or surfaces.get(surface_owner(contact))


def to_json(surfaces: Mapping[str, Shape]) -> str:
    return json.dumps({name: asdict(shape) for name, shape in surfaces.items()}, sort_keys=True)


def from_json(text: str) -> dict[str, Shape]:
    """``to_json``'s surfaces; what is not a shape is left out (a bag written by something else)."""
    try:
        document = json.loads(text)
    except ValueError:
        return {}
    out = {}
    for name, fields in document.items() if isinstance(document, dict) else ():
        try:
            given: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()}
            out[str(name)] = Shape(**given)
        except (TypeError, AttributeError):
            continue
    return out
