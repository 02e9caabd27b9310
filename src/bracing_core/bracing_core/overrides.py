"""``--set KEY=VALUE`` overrides of scenario parameters, for bracing-pair, bracing-sweep and bracing-study.

KEY is a flat parameter name as in the scenario YAML (``input_mode``, ``hand.kp``,
``contacts.elbow.desired_normal_force``, ``duration`` ...). A key of the ``/**`` section
(robot, motors, contacts, input mode) goes to both nodes, a simulator or controller key to
that node only. VALUE is YAML, read as the nodes' rcl reads ``-p KEY:=VALUE``: ``torque``, ``300``,
``true``, ``1e-3``, ``[300, 300]``, ``[y, z]`` (axis names), ``[]``.

A sweep gives several values separated by commas: ``--set hand.kp=[300,300],[150,150]``.
Commas inside brackets or quotes belong to the value, so a list is one value.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_core import rcl_yaml, schema
from bracing_core.params import ConfigError
from bracing_core.rcl_yaml import load_nodes_params

if TYPE_CHECKING:
    from bracing_core.config import SimulatorConfig

SIMULATOR = "bracing_simulator"
CONTROLLER = "bracing_controller"


@dataclass
class NodeOverrides:
    """Overrides split by destination: ``shared`` goes to both nodes (the /** section)."""

    shared: dict[str, Any] = field(default_factory=dict)
    simulator: dict[str, Any] = field(default_factory=dict)
    controller: dict[str, Any] = field(default_factory=dict)

    def for_node(self, node: str) -> dict[str, Any]:
        """What ``node`` (bracing_simulator / bracing_controller) gets, shared first."""
        own = self.simulator if node == SIMULATOR else self.controller
        return {**self.shared, **own}

    def flat(self) -> dict[str, Any]:
        return {**self.shared, **self.simulator, **self.controller}


def split_values(text: str) -> list[str]:
    """``a,[b,c],'d,e'`` -> ``["a", "[b,c]", "'d,e'"]``: commas split only outside brackets and quotes."""
    parts: list[str] = []
    current: list[str] = []
    depth, quote = 0, ""
    for char in text:
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            parts.append("".join(current))
            current = []
            continue
        current.append(char)
    parts.append("".join(current))
    return parts


def parse_value(key: str, text: str) -> Any:
    """One value (a scalar or a flow list), read as the nodes' rcl reads ``-p key:=VALUE`` and given
    the meaning the user wrote (``bracing_core.rcl_yaml``): ``1e-3`` is a number, ``[y,z]`` axis names,
    ``[0,2.0]`` two floats."""
    if not text.strip():
        raise ConfigError(f"--set {key}: empty value")
    return rcl_yaml.conform(key, rcl_yaml.read_value(key, text, f"--set {key}"))


def parse_assignment(text: str) -> tuple[str, list[Any]]:
    """``KEY=V1,V2,...`` -> (KEY, [V1, V2, ...])."""
    key, sep, values = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--set {text!r}: expected KEY=VALUE")
    return key, [parse_value(key, part) for part in split_values(values)]


def destination(key: str) -> str:
    """``shared``, ``bracing_simulator`` or ``bracing_controller``; ConfigError for an unknown key."""
    shared = {p.name for p in schema.SHARED}
    simulator = {p.name for p in schema.SIMULATOR}
    controller = {p.name for p in schema.CONTROLLER}
    if key in shared:
        return "shared"
    parts = key.split(".", 2)  # a field may have dots of its own (force_feedback.kp)
    if len(parts) == 3 and parts[0] == "contacts" and parts[2] in {f.name for f in schema.CONTACT}:
        return "shared"
    if key in simulator and key in controller:  # both nodes have one (e.g. wait_for_recorder)
        return "shared"
    if key in simulator:
        return SIMULATOR
    if key in controller:
        return CONTROLLER
    known = [*shared, *simulator, *controller, "contacts.<name>.<field>"]
    close = difflib.get_close_matches(key, known, n=3)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    raise ConfigError(f"--set {key}: unknown parameter{hint}")


def route(values: Mapping[str, Any]) -> NodeOverrides:
    """Split flat overrides by destination node."""
    out = NodeOverrides()
    for key, value in values.items():
        where = destination(key)
        target = out.shared if where == "shared" else out.simulator if where == SIMULATOR else out.controller
        target[key] = value
    return out


def node_params(config: str | Path, *layers: NodeOverrides | Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The one assembly of a run's parameters (bracing-pair, the launch file, in-process runs, sweeps,
    studies, the optimiser): each node's complete flat parameters, by node name, from the scenario
    file, then each layer in order (a later one wins). A layer is flat names, routed here to their
    node (``route``: ConfigError for an unknown name), or a ``NodeOverrides`` routed already."""
    return with_layers(load_nodes_params(config, (SIMULATOR, CONTROLLER)), *layers)


def with_layers(
    params: Mapping[str, Mapping[str, Any]], *layers: NodeOverrides | Mapping[str, Any]
) -> dict[str, dict[str, Any]]:
    """``node_params``' layering on parameters read already (a copy; a later layer wins)."""
    out = {node: dict(own) for node, own in params.items()}
    for layer in layers:
        routed = layer if isinstance(layer, NodeOverrides) else route(layer)
        for node, own in out.items():
            own.update(routed.for_node(node))
    return out


def validate(config: Path, overrides: NodeOverrides) -> SimulatorConfig:
    """Both nodes' typed configurations build (no model is loaded: cheap); the ConfigError names
    the parameter, prefixed with the overrides that led to it."""
    from bracing_core.config import SimulatorConfig  # pinocchio: bracing-pair's start needs only the schema
    from bracing_core.controller_config import ControllerConfig

    params = node_params(config, overrides)
    search = [config.resolve().parent]
    try:
        sim = SimulatorConfig.from_params(params[SIMULATOR], search)
        ControllerConfig.from_params(params[CONTROLLER], search)
    except ConfigError as exc:
        given = ", ".join(f"{k}={format_value(v)}" for k, v in overrides.flat().items())
        raise ConfigError(f"{exc}" + (f" (with --set {given})" if given else "")) from None
    return sim


def format_value(value: Any) -> str:
    """The --set spelling of a value (round-trips through parse_value)."""
    if isinstance(value, list):
        return "[" + ",".join(format_value(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def parse_single(assignments: Iterable[str]) -> dict[str, Any]:
    """bracing-pair's ``--set``: one value per key."""
    out: dict[str, Any] = {}
    for text in assignments:
        key, values = parse_assignment(text)
        if len(values) != 1:
            raise ConfigError(
                f"--set {key}: one value expected, got {len(values)} (a list is written in brackets: [a,b])"
            )
        destination(key)
        if key in out:
            raise ConfigError(f"--set {key}: given twice")
        out[key] = values[0]
    return out


def parse_sweep(assignments: Sequence[str]) -> dict[str, list[Any]]:
    """bracing-sweep's ``--set``: key -> its values, in command-line order."""
    out: dict[str, list[Any]] = {}
    for text in assignments:
        key, values = parse_assignment(text)
        destination(key)
        if key in out:
            raise ConfigError(f"--set {key}: given twice")
        out[key] = values
    return out
