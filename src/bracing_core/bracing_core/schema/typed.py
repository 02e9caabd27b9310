"""The typed values of a node's parameters, derived at import from the schema's tables.

Each section of flat names becomes a frozen dataclass: one field per parameter, typed from its kind, and one
field per dotted group, itself such a class (``robot.urdf`` is ``values.robot.urdf``, a contact's
``force_feedback.kp`` is ``contact.force_feedback.kp``). The classes are made from the tables, so adding a
parameter to the schema adds its field: there is no second list of names to keep in step.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from functools import reduce
from typing import TYPE_CHECKING, Any, ClassVar

from bracing_core.schema.param import ABSENT, REQUIRED, Kind, Param

_TYPES: dict[Kind, Any] = {
    Kind.DOUBLE: float,
    Kind.INTEGER: int,
    Kind.BOOL: bool,
    Kind.STRING: str,
    Kind.DOUBLE_ARRAY: tuple[float, ...],
    Kind.STRING_ARRAY: tuple[str, ...],
}


class Section:
    """A section of parameters, typed: a frozen dataclass made by :func:`section_class`."""

    params: ClassVar[dict[str, Param]]  # field -> its Param (the leaves of this section)
    sections: ClassVar[dict[str, type[Section]]]  # field -> the class of its dotted group

    if TYPE_CHECKING:  # the fields are made from the tables at import

        def __getattr__(self, name: str) -> Any: ...


def value_type(param: Param) -> Any:
    """The Python type of ``param``'s read value (``None`` where it may be left out or is needed only under
    another setting; a word instead of numbers where it takes one)."""
    kind = _TYPES[param.kind]
    if param.words:
        kind = kind | str
    if param.default is ABSENT or (param.default is REQUIRED and param.required_if is not None):
        kind = kind | None
    return kind


def _class_name(path: str) -> str:
    return "".join(part.title().replace("_", "") for part in path.replace(".", "_").split("_")) or "Values"


def section_class(name: str, params: Sequence[Param]) -> type[Section]:
    """A frozen dataclass named ``name`` with a field per parameter of ``params`` and per dotted group."""
    leaves: dict[str, Param] = {}
    groups: dict[str, list[Param]] = {}
    for param in params:
        head, dot, rest = param.name.partition(".")
        if dot:
            groups.setdefault(head, []).append(dataclasses.replace(param, name=rest))
        else:
            leaves[head] = param
    sections = {group: section_class(name + _class_name(group), members) for group, members in groups.items()}
    fields = [(field, value_type(param)) for field, param in leaves.items()]
    fields += [(group, kind) for group, kind in sections.items()]
    namespace = {"params": leaves, "sections": sections, "__doc__": f"{name}: {', '.join(f for f, _ in fields)}"}
    return dataclasses.make_dataclass(name, fields, bases=(Section,), frozen=True, namespace=namespace)


def build(kind: type[Section], flat: Mapping[str, Any], prefix: str = "") -> Section:
    """The ``kind`` of the flat values ``flat`` (every name of it under ``prefix``)."""
    values = {field: flat[prefix + field] for field in kind.params}
    values |= {group: build(sub, flat, f"{prefix}{group}.") for group, sub in kind.sections.items()}
    return kind(**values)


def lookup(section: Section, name: str) -> Any:
    """The value of the flat ``name`` in ``section`` (a node's declaration walks the names the schema lists)."""
    return reduce(getattr, name.split("."), section)


def flat_names(kind: type[Section], prefix: str = "") -> list[str]:
    """Every flat parameter name ``kind`` has a field for, in field order."""
    names = [prefix + field for field in kind.params]
    for group, sub in kind.sections.items():
        names += flat_names(sub, f"{prefix}{group}.")
    return names


def fields_of(section: Section, names: Sequence[str] | None = None) -> dict[str, Any]:
    """``section``'s parameter fields (``names``, or every leaf) by name: the keyword arguments of a config
    class whose fields are the section's (``PlantError``, ``SensorConfig``)."""
    return {name: getattr(section, name) for name in (section.params if names is None else names)}
