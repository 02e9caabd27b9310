"""Every parameter of both nodes, described once, as data.

A :class:`Param` is a name, a type, a default, a unit, a description and its bounds (or
choices, or length). From these tables everything else is derived: the nodes declare typed
ROS parameters with a ``ParameterDescriptor`` (``bracing_ros.parameters``), :func:`read`
validates a flat parameter dict into typed values for the configuration classes
(``bracing_core.config``), and ``tools/docs_reference.py`` writes the docs site's reference.

Scenario files have a ``/**`` section read by both nodes (:data:`SHARED`, and the per-contact
fields :data:`CONTACT` under ``contacts.<name>.``) and one section per node
(:data:`SIMULATOR`, :data:`CONTROLLER`). ``tunable`` parameters can be set while the
controller runs; ``per_run`` ones while either node runs, taken from its next run on
(``bracing_core.run_parameters``); every other one needs a fresh start.
"""

from bracing_core.schema.contact import CONTACT
from bracing_core.schema.controller import CONTROLLER
from bracing_core.schema.param import ABSENT, REQUIRED, Kind, Param, PerJoint, trajectory_params
from bracing_core.schema.reading import (
    CONTACT_VALUES,
    NODE_PARAMETERS,
    NODE_VALUES,
    SHARED_VALUES,
    TRAJECTORY_VALUES,
    Values,
    all_names,
    check_known,
    contact_fields,
    contact_name,
    contact_values,
    default,
    find,
    get_bool,
    get_float,
    get_floats,
    get_int,
    get_str,
    get_strs,
    node_schema,
    read,
    read_value,
)
from bracing_core.schema.shared import LOG_THROTTLE_PERIOD, MAX_MESSAGE_ELEMENTS, MAX_NAME_LENGTH, SHARED
from bracing_core.schema.simulator import PLANT_ERROR, SENSORS, SIMULATOR
from bracing_core.schema.typed import (
    Section,
    at_defaults,
    build,
    fields_of,
    flat_names,
    lookup,
    own_fields,
    section_class,
    typed_default,
    value_type,
)

__all__ = [
    "ABSENT",
    "CONTACT",
    "CONTACT_VALUES",
    "CONTROLLER",
    "LOG_THROTTLE_PERIOD",
    "MAX_MESSAGE_ELEMENTS",
    "MAX_NAME_LENGTH",
    "NODE_PARAMETERS",
    "NODE_VALUES",
    "PLANT_ERROR",
    "REQUIRED",
    "SENSORS",
    "SHARED",
    "SHARED_VALUES",
    "SIMULATOR",
    "TRAJECTORY_VALUES",
    "Kind",
    "Param",
    "PerJoint",
    "Section",
    "Values",
    "all_names",
    "at_defaults",
    "build",
    "check_known",
    "contact_fields",
    "contact_name",
    "contact_values",
    "default",
    "fields_of",
    "find",
    "flat_names",
    "get_bool",
    "get_float",
    "get_floats",
    "get_int",
    "get_str",
    "get_strs",
    "lookup",
    "node_schema",
    "own_fields",
    "read",
    "read_value",
    "reference_markdown",
    "section_class",
    "trajectory_params",
    "typed_default",
    "value_type",
]


def reference_markdown() -> str:
    """The parameter reference (``tools/docs_reference.py`` writes it to docs/reference/parameters.md)."""
    sections = (
        ("`/**` (both nodes)", SHARED),
        ("`/**`, per contact: `contacts.<name>.`", CONTACT),
        ("`bracing_simulator`", SIMULATOR),
        ("`bracing_controller`", CONTROLLER),
    )
    out: list[str] = []
    for title, params in sections:
        out += [
            f"**{title}**",
            "",
            "| parameter | type | default | unit | bounds | tunable | per run | meaning |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for p in params:
            who = "" if p.nodes == ("simulator", "controller") else f" ({', '.join(p.nodes)})"
            tunable, per_run = ("yes" if p.tunable else ""), ("yes" if p.per_run else "")
            meaning = p.description.replace("|", "\\|") + who
            bounds = p.bounds_text().replace("|", "\\|")
            row = [f"`{p.name}`", p.kind.value, p.default_text(), p.unit, bounds, tunable, per_run]
            out.append("| " + " | ".join([*row, meaning]) + " |")
        out.append("")
    return "\n".join(out)
