"""The typed values of a node's parameters, derived at import from the schema's tables.

Each section of flat names becomes a frozen dataclass: one field per parameter, typed from its kind, and one
field per dotted group, itself such a class (``robot.urdf`` is ``values.robot.urdf``, a contact's
``force_feedback.kp`` is ``contact.force_feedback.kp``). The classes are made from the tables, so adding a
parameter to the schema adds its field: there is no second list of names to keep in step. Parameters that
several sections have are one class, their base: both nodes' shared ones (``SharedValues``), a task's path
(``TrajectoryValues``: the hand's and each brace's).
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

    params: ClassVar[dict[str, Param]] = {}  # field -> its Param (the leaves of this section)
    sections: ClassVar[dict[str, type[Section]]] = {}  # field -> the class of its dotted group

    if TYPE_CHECKING:  # the fields are made from the tables at import
        __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

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


def _split(params: Sequence[Param]) -> tuple[dict[str, Param], dict[str, list[Param]]]:
    """``params`` as this section's own parameters (by field) and its dotted groups' (by group, names shortened)."""
    leaves: dict[str, Param] = {}
    groups: dict[str, list[Param]] = {}
    for param in params:
        head, dot, rest = param.name.partition(".")
        if dot:
            groups.setdefault(head, []).append(dataclasses.replace(param, name=rest))
        else:
            leaves[head] = param
    return leaves, groups


def _check_base(name: str, base: type[Section], leaves: Mapping[str, Param], groups: Mapping[str, Any]) -> None:
    """A section may give its base's parameters their own defaults, of the same type; any other field is new."""
    inherited = base.params
    retyped = [f for f, p in leaves.items() if f in inherited and value_type(p) != value_type(inherited[f])]
    clash = sorted(set(groups) & (inherited.keys() | base.sections.keys()))
    clash += sorted(set(leaves) & base.sections.keys())
    if retyped or clash:
        raise ValueError(f"{name}: {', '.join(retyped + clash)} already a field of {base.__name__}")


def section_class(
    name: str, params: Sequence[Param], base: type[Section] = Section, bases: Mapping[str, type[Section]] = {}
) -> type[Section]:
    """A frozen dataclass named ``name`` with a field per parameter of ``params`` and per dotted group, after the
    fields of ``base``: a class made once for parameters several sections have (both nodes' shared ones, a task's
    path), whose parameters ``params`` may list again with their own defaults. ``bases``: the base of a dotted
    group by its path."""
    leaves, groups = _split(params)
    _check_base(name, base, leaves, groups)
    inherited = base.params
    sections = {
        group: section_class(name + _class_name(group), members, bases.get(group, Section), _under(bases, group))
        for group, members in groups.items()
    }
    fields = [(field, value_type(param)) for field, param in leaves.items() if field not in inherited]
    fields += [(group, kind) for group, kind in sections.items()]
    namespace = {
        "params": inherited | leaves,
        "sections": base.sections | sections,
        "__doc__": f"{name}: {', '.join([*inherited, *base.sections, *(f for f, _ in fields)])}",
    }
    return dataclasses.make_dataclass(name, fields, bases=(base,), frozen=True, namespace=namespace)


def _under(bases: Mapping[str, type[Section]], group: str) -> dict[str, type[Section]]:
    """The entries of ``bases`` inside ``group``, by their path there."""
    return {path[len(group) + 1 :]: kind for path, kind in bases.items() if path.startswith(group + ".")}


def own_fields(kind: type[Section]) -> tuple[list[str], list[str]]:
    """The parameter fields and the group fields ``kind`` declares itself (not its base's)."""
    base: type[Section] = kind.__mro__[1]  # section_class's one base
    leaves = [field for field in kind.params if field not in base.params]
    return leaves, [group for group in kind.sections if group not in base.sections]


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


def fields_of(section: Section) -> dict[str, Any]:
    """Every field of ``section`` (parameters and groups) by name: the keyword arguments of a class derived from
    its class (``SimulatorConfig``, ``PlantError``) that takes them as they were read."""
    return {field.name: getattr(section, field.name) for field in dataclasses.fields(section)}


def at_defaults(section: Section, but: Sequence[str] = ()) -> bool:
    """Whether every parameter field of ``section`` (``but`` those) holds its schema default."""
    return all(getattr(section, f) == typed_default(p) for f, p in section.params.items() if f not in but)


def typed_default(param: Param) -> Any:
    """``param``'s default (a value, not REQUIRED or PerJoint) as :func:`read` gives it: a list as a tuple."""
    return tuple(param.default) if isinstance(param.default, list) else param.default
