"""Reading a node's flat parameters into typed, checked values (:func:`read`), each refusal naming
the parameter; the node's schema and the lookups by flat name."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, Literal, TypeVar, overload

from bracing_core.numbers import number
from bracing_core.params import ConfigError, Params
from bracing_core.schema.contact import CONTACT
from bracing_core.schema.controller import CONTROLLER
from bracing_core.schema.param import ABSENT, REQUIRED, Kind, Param, PerJoint, trajectory_params
from bracing_core.schema.shared import SHARED
from bracing_core.schema.simulator import SIMULATOR
from bracing_core.schema.typed import Section, build, lookup, section_class

if TYPE_CHECKING:  # the classes as mypy sees them (tools/values_stubs.py writes them from the schema)
    from bracing_core.schema.typed_values import ContactValues, ControllerValues, SimulatorValues

P = TypeVar("P", bound=Section)

NODE_PARAMETERS: dict[str, tuple[Param, ...]] = {"simulator": SIMULATOR, "controller": CONTROLLER}


def node_schema(node: str) -> tuple[Param, ...]:
    """The global parameters of ``node`` ("simulator" or "controller"): SHARED then its own."""
    return (*SHARED, *NODE_PARAMETERS[node])


def default(node: str, name: str) -> Any:
    """The schema's default of ``node``'s parameter ``name``."""
    param = find(node, name)
    if param is None or param.default is REQUIRED:
        raise KeyError(f"{node} has no parameter {name} with a default")
    return param.default


def contact_fields(node: str) -> tuple[Param, ...]:
    return tuple(p for p in CONTACT if node in p.nodes)


def contact_name(name: str, field: str) -> str:
    return f"contacts.{name}.{field}"


def _joint_hint(values: Sequence[str], read: Mapping[str, Any]) -> str:
    """What a per-joint list's length counts. Per-joint lists follow robot.joint_names, locked joints
    listed there included (their values unused): a list then stays as it is when a joint is locked
    or unlocked for a run (``--set robot.locked_joints=[...]``). A joint locked without being listed
    there (a gripper's fingers) needs no entry: the hint says which listed ones count though locked."""
    locked = [name for name in values if name in (read.get("robot.locked_joints") or ())]
    if not locked:
        return f"one per joint of robot.joint_names ({len(values)})"
    return (
        f"one per joint of robot.joint_names ({len(values)}), the locked {', '.join(locked)} included (values "
        "unused; a joint in robot.locked_joints but not in robot.joint_names needs none)"
    )


_HINTS: dict[str, Callable[[Sequence[str], Mapping[str, Any]], str]] = {
    "robot.joint_names": _joint_hint,
    "hand.axes": lambda values, read: f"one per hand axis {list(values)}",
    "hand.orientation.axes": lambda values, read: f"one per orientation axis {list(values)}",
    "brace_axes": lambda values, read: f"one per brace axis {list(values)}",
    "robot.locked_joints": lambda values, read: f"one per locked joint {list(values)}",
}


# -- typed reads: every parameter's value checked and typed here, in one pass (``read``) --------------
def check_known(
    params: Params, known: Iterable[str], dynamic_prefixes: Mapping[str, Iterable[str]] | None = None
) -> None:
    """Reject parameters that are not in the schema.

    ``dynamic_prefixes`` maps a prefix such as ``"contacts."`` to the fields allowed in
    its named sub-sections (``contacts.<any name>.<field>``).
    """
    known_set = set(known) | {"use_sim_time", "start_type_description_service"}
    dynamic = {prefix: set(fields) for prefix, fields in (dynamic_prefixes or {}).items()}
    unknown = []
    for name in params:
        if name in known_set:
            continue
        for prefix, fields in dynamic.items():
            rest = name[len(prefix) :].split(".", 1) if name.startswith(prefix) else []
            if len(rest) == 2 and rest[1] in fields:
                break
        else:
            unknown.append(name)
    if unknown:
        raise ConfigError(f"unknown parameter(s): {', '.join(sorted(unknown))}")


def get_float(
    params: Params, name: str, default: float | None = None, *, minimum: float | None = None, positive: bool = False
) -> float:
    value = params.get(name, default)
    if not number(value):
        raise ConfigError(f"{name}: expected a finite number, got {value!r}")
    if positive and value <= 0.0:
        raise ConfigError(f"{name}: must be > 0, got {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(f"{name}: must be >= {minimum}, got {value!r}")
    return float(value)


def get_int(params: Params, name: str, default: int, *, minimum: int | None = None) -> int:
    value = params.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{name}: expected an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(f"{name}: must be >= {minimum}, got {value!r}")
    return int(value)


def get_bool(params: Params, name: str, default: bool) -> bool:
    value = params.get(name, default)
    if not isinstance(value, bool):
        raise ConfigError(f"{name}: expected true or false, got {value!r}")
    return value


def get_str(params: Params, name: str, default: str | None = None, *, choices: Sequence[str] | None = None) -> str:
    value = params.get(name, default)
    if not isinstance(value, str) or (default is None and not value):
        raise ConfigError(f"{name}: expected a non-empty string, got {value!r}")
    if choices is not None and value not in choices:
        raise ConfigError(f"{name}: expected one of {', '.join(choices)}, got {value!r}")
    return value


def get_floats(params: Params, name: str, default: Sequence[float] | None = None) -> tuple[float, ...]:
    """A list of finite numbers; an empty or unset list reads as ``()``."""
    value = params.get(name, default)
    if value is None:
        value = []
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value]
    if not isinstance(value, (list, tuple)) or not all(number(v) for v in value):
        raise ConfigError(f"{name}: expected a list of finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def get_strs(params: Params, name: str, default: Sequence[str] = ()) -> tuple[str, ...]:
    value = params.get(name, default)
    if value is None:
        return ()
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v for v in value):
        # A node started by hand reads a bare y as true (rcl, YAML 1.1); bracing's own readers mend it.
        hint = ' (YAML 1.1 reads a bare y or n as true/false: quote it, "y")' if _has_bool(value) else ""
        raise ConfigError(f"{name}: expected a list of non-empty strings, got {value!r}{hint}")
    if len(set(value)) != len(value):
        raise ConfigError(f"{name}: duplicate entries in {list(value)}")
    return tuple(value)


def _has_bool(value: Any) -> bool:
    return isinstance(value, (list, tuple)) and any(isinstance(v, bool) for v in value)


def read_value(param: Param, name: str, params: Params, read: Mapping[str, Any]) -> Any:
    """One parameter's typed value from ``params`` (its default if unset), or a ConfigError naming
    ``name``. ``read`` holds the values read so far (list lengths and conditions refer to them)."""
    required = param.default is REQUIRED and (
        param.required_if is None or read.get(param.required_if[0]) == param.required_if[1]
    )
    if param.words and isinstance(params.get(name), str):
        if params[name] not in param.words:
            raise ConfigError(f"{name}: expected {' or '.join(param.words)} or 3 numbers, got {params[name]!r}")
        return params[name]
    if ((param.default is REQUIRED and not required) or param.default is ABSENT) and name not in params:
        return None  # required only under another setting, or absent by choice
    if param.kind is Kind.DOUBLE_ARRAY and param.default is REQUIRED and not required and not params.get(name):
        return None  # an empty list for a value only another setting needs (a plane's sphere centre)
    default: Any = None if param.default is ABSENT else param.default
    if isinstance(default, PerJoint):
        default = [default.value] * len(read["robot.joint_names"])
    if param.kind is Kind.DOUBLE:
        return get_float(params, name, default, minimum=param.minimum, positive=param.positive)
    if param.kind is Kind.INTEGER:
        return get_int(params, name, default, minimum=None if param.minimum is None else int(param.minimum))
    if param.kind is Kind.BOOL:
        return get_bool(params, name, default)
    if param.kind is Kind.STRING:
        return get_str(params, name, default, choices=param.choices or None)
    if param.kind is Kind.STRING_ARRAY:
        value = get_strs(params, name, default if default is not None else ())
        if required and not value:
            raise ConfigError(f"{name}: expected a non-empty list, got none")
        if isinstance(param.length, int) and len(value) != param.length:
            raise ConfigError(f"{name}: expected {param.length} values, got {len(value)}")
        return value
    return _read_floats(param, name, params, read, default)


def _read_floats(param: Param, name: str, params: Params, read: Mapping[str, Any], default: Any) -> tuple[float, ...]:
    length: int | None = param.length if isinstance(param.length, int) else None
    hint = ""
    if isinstance(param.length, str):
        reference = read[param.length]
        length, hint = len(reference), _HINTS[param.length](reference, read)
    value = get_floats(params, name, default)
    if param.default is not REQUIRED and param.may_be_empty and not value:
        if isinstance(param.default, PerJoint):  # empty: the per-joint default
            return tuple(float(param.default.value) for _ in range(length or 0))
        return ()
    if length is not None and len(value) != length:
        if param.may_be_empty:
            what = f" ({hint})" if hint else ""
            raise ConfigError(f"{name}: expected {length} values{what} or an empty list, got {list(value)}")
        raise ConfigError(f"{name}: expected {length} values{f' ({hint})' if hint else ''}, got {len(value)}")
    if param.positive and any(v <= 0.0 for v in value):
        raise ConfigError(f"{name}: values must be > 0, got {list(value)}")
    if param.minimum is not None and any(v < param.minimum for v in value):
        raise ConfigError(f"{name}: values must be >= {param.minimum:g}, got {list(value)}")
    return value


SHARED_VALUES = section_class("SharedValues", SHARED)
"""The typed values both nodes read from the ``/**`` section: a field per :data:`SHARED` entry, the base of each
node's class."""
TRAJECTORY_VALUES = section_class("TrajectoryValues", trajectory_params("", "hold", "a task's desired path"))
"""A task's path (``trajectory_params``): the base of the hand's (``hand.trajectory``) and each brace's."""
NODE_VALUES: dict[str, type[Section]] = {
    node: section_class(
        f"{node.title()}Values", NODE_PARAMETERS[node], SHARED_VALUES, {"hand.trajectory": TRAJECTORY_VALUES}
    )
    for node in NODE_PARAMETERS
}
"""Each node's typed values: the shared ones, then a field per parameter of its own (dotted groups nested)."""
CONTACT_VALUES = section_class("ContactValues", CONTACT, bases={"trajectory": TRAJECTORY_VALUES})
"""A contact's typed values: a field per :data:`CONTACT` entry (a node's unread ones hold their default)."""


@dataclass(frozen=True)
class Values(Generic[P]):
    """What :func:`read` gives: the node's parameters typed (``values.params.robot.urdf``), and each contact's
    (``values.contacts[name].frame``), in contacts.names order."""

    node: str
    params: P  # a NODE_VALUES[node]
    contacts: dict[str, ContactValues]  # CONTACT_VALUES per contact name

    def flat(self) -> list[tuple[str, Param, Any]]:
        """Every parameter the node declares: its flat ROS name, its Param and its read value."""
        out = [(p.name, p, lookup(self.params, p.name)) for p in node_schema(self.node)]
        for contact, own in self.contacts.items():
            out += [(contact_name(contact, p.name), p, lookup(own, p.name)) for p in contact_fields(self.node)]
        return out


def contact_values(own: Mapping[str, Any]) -> Section:
    """A contact's typed values from its read fields ``own`` (by field name); a field not in ``own`` (one the
    node does not read) holds its default, or None if it has none."""
    unread = {p.name: None if p.default in (REQUIRED, ABSENT) else p.default for p in CONTACT}
    return build(CONTACT_VALUES, unread | dict(own))


@overload
def read(node: Literal["simulator"], params: Params) -> Values[SimulatorValues]: ...
@overload
def read(node: Literal["controller"], params: Params) -> Values[ControllerValues]: ...
@overload
def read(node: str, params: Params) -> Values[Any]: ...
def read(node: str, params: Params) -> Values[Any]:
    """Validate ``node``'s flat parameters against its schema: unknown names, types, bounds,
    lengths. Each ConfigError names the parameter."""
    schema, fields = node_schema(node), contact_fields(node)
    check_known(params, [p.name for p in schema], {"contacts.": [f.name for f in CONTACT]})
    values: dict[str, Any] = {}
    for param in schema:
        values[param.name] = read_value(param, param.name, params, values)
    typed = build(NODE_VALUES[node], values)
    contacts: dict[str, Any] = {}
    for contact in typed.contacts.names:
        own: dict[str, Any] = {}
        for field in fields:
            own[field.name] = read_value(field, contact_name(contact, field.name), params, {**values, **own})
        contacts[contact] = contact_values(own)
    return Values(node, typed, contacts)


def all_names(node: str, contacts: Sequence[str]) -> list[str]:
    """Every parameter ``node`` declares for these contact names."""
    names = [p.name for p in node_schema(node)]
    names += [contact_name(c, f.name) for c in contacts for f in contact_fields(node)]
    return names


def find(node: str, name: str) -> Param | None:
    """The Param behind a flat name of ``node`` (``contacts.<any>.<field>`` included)."""
    for param in node_schema(node):
        if param.name == name:
            return param
    parts = name.split(".", 2)
    if len(parts) == 3 and parts[0] == "contacts":
        for field in contact_fields(node):
            if field.name == parts[2]:
                return field
    return None
