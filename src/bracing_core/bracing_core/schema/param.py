"""The parameter's description: a :class:`Param` (name, type, default, unit, description, bounds),
and the parameters of a task's desired path (:func:`trajectory_params`), used by several sections."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any


class Kind(str, Enum):  # noqa: UP042 (values are ROS parameter type names)
    DOUBLE = "double"
    INTEGER = "integer"
    BOOL = "bool"
    STRING = "string"
    DOUBLE_ARRAY = "double_array"
    STRING_ARRAY = "string_array"


@dataclass(frozen=True)
class PerJoint:
    """A default of one ``value`` per joint of robot.joint_names."""

    value: float


REQUIRED = None  # a Param without a default must be given


class _Absent:
    """The default of a parameter that may be left out, and means something by its absence."""

    def __repr__(self) -> str:
        return "ABSENT"


ABSENT = _Absent()  # read as None when not given (e.g. no desired_normal_force: an obstacle)


@dataclass(frozen=True)
class Param:
    name: str  # flat ROS name; for CONTACT fields, the part after contacts.<name>.
    kind: Kind
    default: Any  # REQUIRED, a value, or PerJoint
    description: str
    unit: str = ""
    minimum: float | None = None  # inclusive (arrays: every value)
    positive: bool = False  # > 0 (arrays: every value)
    choices: tuple[str, ...] = ()
    # a DOUBLE_ARRAY that also takes one of these words instead of numbers (contacts.<name>.point: a cylinder's
    # axis point, or where a plane's or sphere's contact point is)
    words: tuple[str, ...] = ()
    length: int | str | None = None  # a count, or the list parameter whose length it must match
    may_be_empty: bool = False  # with a length: an empty list is allowed too (and means a default)
    required_if: tuple[str, str] | None = None  # REQUIRED only when parameter [0] equals [1]
    tunable: bool = False  # the controller accepts a new value while it runs
    # each node accepts a new value while it runs and builds its next run from it, as a fresh process would (the
    # simulator at reset_simulation, the controller when its states go back in time); bracing_core.run_parameters
    per_run: bool = False
    nodes: tuple[str, ...] = ("simulator", "controller")  # CONTACT fields: who uses it

    @property
    def required(self) -> bool:
        return self.default is REQUIRED and self.required_if is None

    def default_text(self) -> str:
        if self.default is REQUIRED:
            if self.required_if is None:
                return "required"
            return f"required if {self.required_if[0]} is {self.required_if[1]}"
        if isinstance(self.default, PerJoint):
            return f"{self.default.value:g} per joint"
        if self.default is ABSENT:
            return "none"
        if isinstance(self.default, bool):
            return str(self.default).lower()
        if isinstance(self.default, (list, tuple)):
            # As it is written in a scenario file: a bare y would be read as true (YAML 1.1, rcl).
            return "[" + ", ".join(f'"{v}"' if isinstance(v, str) else str(v) for v in self.default) + "]"
        return repr(self.default) if isinstance(self.default, str) else f"{self.default:g}"

    def bounds_text(self) -> str:
        parts = []
        if self.words:
            parts.append(" | ".join(self.words) + " | 3 numbers")
        if self.choices:
            parts.append(" | ".join(self.choices))
        if self.positive:
            parts.append("> 0")
        if self.minimum is not None:
            parts.append(f">= {self.minimum:g}")
        if isinstance(self.length, int):
            parts.append(f"{self.length} values" + (" or empty" if self.may_be_empty else ""))
        elif isinstance(self.length, str):
            parts.append(f"one per {self.length}" + (" or empty" if self.may_be_empty else ""))
        return ", ".join(parts)


def trajectory_params(
    prefix: str, default_type: str, what: str, nodes: tuple[str, ...] = ("simulator", "controller")
) -> tuple[Param, ...]:
    """The parameters of a task's desired path under ``prefix`` (the hand's and each brace's)."""
    kind = prefix + "type"
    return (
        Param(kind, Kind.STRING, default_type, what, choices=("hold", "circle", "waypoints"), nodes=nodes),
        Param(
            prefix + "center",
            Kind.DOUBLE_ARRAY,
            REQUIRED,
            "circle center",
            "m",
            length=3,
            required_if=(kind, "circle"),
            nodes=nodes,
        ),
        Param(
            prefix + "radius",
            Kind.DOUBLE,
            REQUIRED,
            "circle radius",
            "m",
            minimum=0.0,
            required_if=(kind, "circle"),
            nodes=nodes,
        ),
        Param(prefix + "period", Kind.DOUBLE, 10.0, "circle: time of one turn", "s", positive=True, nodes=nodes),
        Param(
            prefix + "direction",
            Kind.DOUBLE,
            1.0,
            "circle: +1 counter-clockwise in the plane, -1 clockwise (the paper: -1)",
            nodes=nodes,
        ),
        Param(prefix + "phase", Kind.DOUBLE, 0.0, "circle: angle at t = 0", "rad", nodes=nodes),
        Param(
            prefix + "plane",
            Kind.STRING_ARRAY,
            ["y", "z"],
            "circle: its plane, the world axes of cos and sin",
            length=2,
            nodes=nodes,
        ),
        Param(
            prefix + "waypoints",
            Kind.DOUBLE_ARRAY,
            REQUIRED,
            "waypoints: [x1, y1, z1, x2, y2, z2, ...], visited in order from the first measured position, "
            "rest to rest, each segment a minimum-jerk (quintic) profile; then held",
            "m",
            required_if=(kind, "waypoints"),
            nodes=nodes,
        ),
        Param(
            prefix + "segment_time",
            Kind.DOUBLE,
            1.0,
            "waypoints: duration of each segment",
            "s",
            positive=True,
            nodes=nodes,
        ),
        Param(
            prefix + "start_ramp",
            Kind.DOUBLE,
            0.0,
            "> 0: the reference starts where the task point is, at rest: over this T the path's time runs as "
            "tau = T (x^3 - x^4 / 2), x = t / T (then t - T / 2: the path runs T / 2 late) and the offset from "
            "the first measured position to the path's start fades on a minimum-jerk profile, so the law's first "
            "steps ask for no jump (the kick of a voltage-input start); 0: the path as given",
            "s",
            minimum=0.0,
            nodes=nodes,
        ),
    )
