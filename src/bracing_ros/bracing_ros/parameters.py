"""A node's ROS parameters from its schema (``bracing_core.schema``): typed declarations with
descriptors, so ``ros2 param list/describe/get`` tell a user what each one is, and a set is
either taken (``tunable``, ``per_run``) or refused with the reason.

Validation stays in the ROS-free core: the node hands its flat parameters to the typed
configuration (which names the parameter in every error), then declares every parameter of
its schema with the validated value.
"""

from __future__ import annotations

import array
import sys
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from bracing_core import schema
from bracing_core.schema import Kind, Param

_TYPES = {
    Kind.DOUBLE: Parameter.Type.DOUBLE,
    Kind.INTEGER: Parameter.Type.INTEGER,
    Kind.BOOL: Parameter.Type.BOOL,
    Kind.STRING: Parameter.Type.STRING,
    Kind.DOUBLE_ARRAY: Parameter.Type.DOUBLE_ARRAY,
    Kind.STRING_ARRAY: Parameter.Type.STRING_ARRAY,
}


def given_parameters(node: Node) -> dict[str, Any]:
    """The flat parameters the node was started with (params files and ``-p``), by name.

    rclpy keeps them in ``Node._parameter_overrides`` and offers no public reader (this is the
    project's one read of it); declaring
    them would need their types first (an empty list reaches rclpy as NOT_SET, which it refuses
    to declare). Reading them here lets the schema name an unknown or mistyped parameter.
    """
    return {name: parameter.value for name, parameter in node._parameter_overrides.items()}


def when_text(param: Param, checked: bool) -> str:
    """When a change of ``param`` is taken, as its descriptor says it (``checked``: see ``declare``)."""
    if param.tunable:
        return ""
    if not checked:
        return " (read-only while the node runs)"
    if param.per_run:
        return " (per run: taken from the node's next run on)"
    return " (needs a fresh start: refused while the node runs)"


def descriptor(param: Param, name: str, checked: bool = False) -> ParameterDescriptor:
    """The ROS descriptor of ``param`` (declared as ``name``; ``checked``: see ``declare``)."""
    unit = f" [{param.unit}]" if param.unit else ""
    text = f"{param.description}{unit}; default {param.default_text()}"
    out = ParameterDescriptor(
        name=name,
        type=_TYPES[param.kind].value,
        description=text,
        additional_constraints=param.bounds_text() + when_text(param, checked),
        read_only=not (param.tunable or checked),
    )
    if param.kind is Kind.DOUBLE and param.minimum is not None:
        out.floating_point_range = [FloatingPointRange(from_value=param.minimum, to_value=sys.float_info.max)]
    if param.kind is Kind.INTEGER and param.minimum is not None:
        out.integer_range = [IntegerRange(from_value=int(param.minimum), to_value=2**63 - 1, step=1)]
    return out


def _ros_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def plain(value: Any) -> Any:
    """A parameter value as the schema reads it (rclpy gives arrays as ``array.array``)."""
    return list(value) if isinstance(value, (list, tuple, array.array)) else value


def declare(node: Node, kind: str, values: schema.Values, checked: bool = False) -> None:
    """Declare every parameter of ``kind``'s schema ("simulator" or "controller") on ``node``,
    typed, described and with its validated value (``schema.read`` of what the node was given).
    ``checked``: the node judges every change itself (``bracing_core.run_parameters``: per-run and tunable ones
    taken, the others refused with the reason), so none is read-only to rclpy; else only tunable ones may change."""
    assert values.node == kind, f"{kind}'s parameters read as {values.node}'s"
    for name, param, value in values.flat():
        # Unset (required only in another mode) or an empty list: declared typed, without a value
        # (rclpy would type an empty list as a byte array).
        default = _TYPES[param.kind] if value is None or value == () else _ros_value(value)
        node.declare_parameter(name, default, descriptor(param, name, checked), ignore_override=True)


def current_values(node: Node, kind: str) -> dict[str, Any]:
    """The node's declared parameters of ``kind``'s schema as a flat dict (unset ones left out)."""
    out: dict[str, Any] = {}
    for name, parameter in node.get_parameters_by_prefix("").items():
        value = parameter.value if isinstance(parameter, Parameter) else parameter
        if value is not None and (schema.find(kind, name) is not None):
            out[name] = plain(value)
    return out
