"""Parameter YAML read the way the nodes' rcl reads it (``rcl_yaml_param_parser``), and written so
that rcl reads it back unchanged.

PyYAML and rcl disagree on plain scalars: rcl reads a bare ``y``, ``n`` (and yes, no, on, off,
true, false) as true/false where PyYAML reads ``y`` as text, ``1e-3`` as a number where PyYAML
reads text, and rcl refuses a list mixing types (``[y, z]`` is [true, "z"] to it; ``[0, 2.0]`` an
integer and a double), an empty value and an alias. A scenario that ran in process killed both
nodes. So every reader here (bracing-pair, the in-process runs, sweeps, studies, ``--set``) types
scalars as rcl does (:func:`scalar`), then :func:`conform` gives each parameter what the user
meant by its schema type: a text parameter the text as written (axis names y/z/x stay names), a
number list with both integers and decimals all floats; what it cannot mend is refused naming the
key and the fix. :func:`dump` writes parameters with every string quoted: what bracing-pair hands
its nodes.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import sys
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bracing_core import schema
from bracing_core.params import ConfigError
from bracing_core.schema import Kind

Value = bool | int | float | str

# rcl_yaml_param_parser's get_value: these plain words are booleans (YAML 1.1), whatever PyYAML says.
_TRUE = frozenset(("Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"))
_FALSE = frozenset(("N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"))
# Then strtol(text, base 0) over the whole text (hex, octal with a leading 0, decimal) ...
_INT = re.compile(r"[+-]?(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
# ... then strtod over the whole text (decimal, hexadecimal, inf, nan), and YAML's own .inf / .nan.
_FLOAT = re.compile(
    r"[+-]?((\d+\.?\d*|\.\d+)(e[+-]?\d+)?|0x([0-9a-f]+\.?[0-9a-f]*|\.[0-9a-f]+)(p[+-]?\d+)?|inf(inity)?|nan(\(\w*\))?)",
    re.IGNORECASE,
)
_YAML_SPECIAL = re.compile(r"[+-]?\.(inf|Inf|INF)|\.(nan|NaN|NAN)")
_STR_TAG = "tag:yaml.org,2002:str"
_SEQ_TAG = "tag:yaml.org,2002:seq"
_INT64 = 2**63

# Parameters rclpy declares itself on every node: a wrong type stops the node before our checks run.
RCLPY_BOOLS = ("use_sim_time", "start_type_description_service")


@dataclass(frozen=True)
class Scalar:
    """One scalar as rcl types it, with its text as written (what a text parameter means)."""

    value: Value
    text: str
    line: int  # 1-based, in the file or value it came from


Leaf = Scalar | list[Scalar]


def scalar(text: str, plain: bool = True) -> Value:
    """``text`` typed as rcl types a scalar: quoted (or ``!!str``) is text; a plain one is a bool,
    an integer (int64), a double or else text, in that order (rcl_yaml_param_parser's get_value)."""
    if not plain:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    if _INT.fullmatch(text):
        integer = _parse_int(text)
        if -_INT64 <= integer < _INT64:  # beyond int64 strtol fails (ERANGE) and strtod reads it
            return integer
    if _YAML_SPECIAL.fullmatch(text):
        return float(text.replace(".", "").lower())
    if _FLOAT.fullmatch(text):
        number = _parse_float(text)
        if number is not None:
            return number
    return text


def _parse_int(text: str) -> int:
    sign = -1 if text.startswith("-") else 1
    body = text.lstrip("+-")
    if body[:2] in ("0x", "0X"):
        return sign * int(body[2:], 16)
    return sign * (int(body, 8) if body.startswith("0") else int(body))


def _parse_float(text: str) -> float | None:
    """strtod's reading of a text ``_FLOAT`` matched; None where it fails with ERANGE (rcl: text)."""
    body = text.lstrip("+-")
    if body[:2].lower() == "0x":
        number = float.fromhex(text)
    else:
        number = float(re.sub(r"\(\w*\)$", "", text))  # nan(chars) is nan
    finite_text = not re.search(r"inf|nan", text, re.IGNORECASE)
    if finite_text and math.isinf(number):
        return None  # overflow
    if finite_text and (0.0 < abs(number) < sys.float_info.min or (number == 0.0 and re.search(r"[1-9]", body))):
        return None  # underflow (glibc sets ERANGE for a subnormal or lost result)
    return number


# -- reading -------------------------------------------------------------------------------------------
def read_document(text: str, source: str, path: Sequence[str] = ()) -> Any:
    """A YAML document's tree (mappings as dicts) with rcl's scalars (:class:`Scalar`) and lists of
    them as leaves; None for an empty document. ConfigError, naming the key, for what rcl refuses
    whatever the parameter: an empty value, an alias, a list of lists or of mappings."""
    try:
        events = list(yaml.parse(text, Loader=yaml.SafeLoader))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source} is not readable YAML: {exc}") from None
    stream = iter(e for e in events if not isinstance(e, (yaml.StreamStartEvent, yaml.DocumentStartEvent)))
    first = next(stream)
    if isinstance(first, (yaml.StreamEndEvent, yaml.DocumentEndEvent)):
        return None
    return _Builder(stream, source).node(first, list(path))


def read_value(name: str, text: str, source: str) -> Leaf:
    """The value of parameter ``name`` as rcl reads ``-p name:=VALUE`` (and bracing's ``--set``):
    a scalar or a flat list."""
    tree = read_document(text, source, [name])
    if tree is None:
        raise ConfigError(f"{source}: no value in {text!r}")
    if isinstance(tree, dict):
        raise ConfigError(f"{source}: expected a value or a list, got a mapping {text!r}")
    return tree


class _Builder:
    """The tree of a document from PyYAML's parse events (which keep what rcl looks at: the
    scalar's text, whether it was quoted, its tag)."""

    def __init__(self, events: Iterator[yaml.Event], source: str) -> None:
        self.events = events
        self.source = source

    def node(self, event: yaml.Event, path: list[str]) -> Any:
        if isinstance(event, yaml.MappingStartEvent):
            return self.mapping(path)
        if isinstance(event, yaml.SequenceStartEvent):
            return self.sequence(path)
        if isinstance(event, yaml.AliasEvent):
            raise ConfigError(self.refused(path, event, f"*{event.anchor} is a YAML alias", "write the value out"))
        assert isinstance(event, yaml.ScalarEvent)
        return self.scalar(event, path)

    def mapping(self, path: list[str]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key in self.events:
            if isinstance(key, yaml.MappingEndEvent):
                return out
            if not isinstance(key, yaml.ScalarEvent):
                raise ConfigError(self.refused(path, key, "a key that is not a name", "keys are plain names"))
            out[key.value] = self.node(next(self.events), [*path, key.value])
        raise AssertionError("unterminated mapping")  # PyYAML has parsed the whole document already

    def sequence(self, path: list[str]) -> list[Scalar]:
        out: list[Scalar] = []
        for item in self.events:
            if isinstance(item, yaml.SequenceEndEvent):
                return out
            if isinstance(item, yaml.ScalarEvent):
                out.append(self.scalar(item, path))
                continue
            what = "an alias" if isinstance(item, yaml.AliasEvent) else "a nested list or mapping"
            raise ConfigError(self.refused(path, item, f"a list holding {what}", "a list holds plain values"))
        raise AssertionError("unterminated list")

    def scalar(self, event: yaml.ScalarEvent, path: list[str]) -> Scalar:
        plain = event.style not in ("'", '"') and event.tag != _STR_TAG
        if plain and not event.value:
            fix = "give one, [] for an empty list, or leave the line out for the default"
            raise ConfigError(self.refused(path, event, "no value", fix))
        return Scalar(scalar(event.value, plain), event.value, event.start_mark.line + 1)

    def refused(self, path: list[str], event: yaml.Event, what: str, fix: str) -> str:
        where = f"line {event.start_mark.line + 1} of {self.source}"
        return f"{parameter_name(path)}: {what} ({where}), which rcl refuses: {fix}"


def parameter_name(path: Sequence[str]) -> str:
    """A parameter's flat name from its path in a params file (the keys after ros__parameters)."""
    keys = list(path)
    if "ros__parameters" in keys:
        keys = keys[keys.index("ros__parameters") + 1 :]
    return ".".join(keys) or "(the document)"


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Leaf]:
    """``{"hand": {"kp": ...}}`` -> ``{"hand.kp": ...}``, as rcl names nested parameters."""
    out: dict[str, Leaf] = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            out.update(flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def node_sections(path: Path, node_name: str) -> dict[str, Leaf]:
    """What a node named ``node_name`` gets from a params file: the ``/**`` and ``<node_name>``
    (or ``/<node_name>``) sections, merged in file order as rcl does, as rcl reads them."""
    return sections_of(params_document(path), path, node_name)


def params_document(path: Path) -> dict[str, Any]:
    """A params file read and parsed (once, whatever number of nodes it is for): its node sections."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(f"params file not found: {path}") from None
    except OSError as exc:
        raise ConfigError(f"params file {path} is not readable: {exc}") from None
    document = read_document(text, str(path))
    if not isinstance(document, dict):
        raise ConfigError(f"params file {path}: expected a mapping of node sections")
    return document


def sections_of(document: Mapping[str, Any], path: Path, node_name: str) -> dict[str, Leaf]:
    """``node_sections`` of a params file parsed already (``params_document``)."""
    params: dict[str, Leaf] = {}
    for section, body in document.items():
        if section in ("/**", node_name, "/" + node_name):
            if not isinstance(body, dict) or not isinstance(body.get("ros__parameters"), dict):
                raise ConfigError(f"params file {path}: section {section!r} needs a ros__parameters mapping")
            params.update(flatten(body["ros__parameters"]))
    return params


# -- what the user meant ---------------------------------------------------------------------------
def kind_of(name: str) -> Kind | None:
    """The schema type of a parameter of either node (``contacts.<any>.<field>`` included)."""
    param = schema.find("controller", name) or schema.find("simulator", name)
    return None if param is None else param.kind


def conform(name: str, leaf: Leaf, source: str = "") -> Any:
    """The value of parameter ``name`` as the user meant it, from what rcl reads (see the module's
    doc). A list rcl would refuse that the parameter's type does not mend is a ConfigError naming the
    key, the fix and where it was written (``source``: a file); any other wrong type is left to the
    schema's checks, which name it too."""
    kind = kind_of(name)
    if isinstance(leaf, Scalar):
        if kind is Kind.STRING:
            return leaf.text
        if name in RCLPY_BOOLS and not isinstance(leaf.value, bool):
            got = f"got {leaf.text!r}{_where(leaf, source)}"
            raise ConfigError(f"{name}: expected true or false (rclpy declares it a bool), {got}")
        return leaf.value
    if kind is Kind.STRING_ARRAY:
        return [item.text for item in leaf]
    values = [item.value for item in leaf]
    if kind is Kind.DOUBLE_ARRAY and _numbers(values) and _mixed(values):
        return [float(v) for v in values]
    if kind is not None and _mixed(values):
        raise ConfigError(refusal(name, leaf) + _where(leaf, source))
    return values


def conform_all(params: Mapping[str, Leaf], source: str = "") -> dict[str, Any]:
    return {name: conform(name, leaf, source) for name, leaf in params.items()}


def _where(leaf: Leaf, source: str) -> str:
    first = leaf if isinstance(leaf, Scalar) else leaf[0]
    return f" (line {first.line} of {source})" if source else ""


def _numbers(values: Sequence[Value]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _mixed(values: Sequence[Value]) -> bool:
    """Whether rcl refuses the list: its items are not all of one type (bool, int, float, str)."""
    return len({type(v) for v in values}) > 1


def refusal(name: str, items: Sequence[Scalar]) -> str:
    """Why rcl refuses the list ``items`` of ``name``, and what to write instead."""
    shown = "[" + ", ".join(item.text for item in items) + "]"
    values = [item.value for item in items]
    if _numbers(values):
        fixed = "[" + ", ".join(repr(float(v)) for v in values) + "]"
        return (
            f"{name}: {shown} mixes integers and decimals, which rcl refuses: write every number as a decimal, {fixed}"
        )
    if any(isinstance(v, bool) for v in values) and any(isinstance(v, str) for v in values):
        fixed = "[" + ", ".join(json.dumps(item.text) for item in items) + "]"
        return (
            f"{name}: {shown} mixes true/false and text as rcl reads it (YAML 1.1 reads a bare y, n, yes, no, on "
            f"or off as true/false), which rcl refuses: quote the text, {fixed}"
        )
    kinds = " and ".join(sorted({_KIND_NAMES[type(v)] for v in values}))
    return f"{name}: {shown} mixes {kinds}, which rcl refuses: a list holds values of one type"


_KIND_NAMES = {bool: "true/false", int: "integers", float: "decimals", str: "text"}


# -- the nodes' own start ------------------------------------------------------------------------------
def explain(argv: Sequence[str]) -> str | None:
    """Why rcl refused the ``--params-file`` and ``-p`` arguments in ``argv`` (a node's command
    line), naming the parameter and the fix; None if none of them is refused here."""
    for option, argument in itertools.pairwise(argv):
        try:
            if option == "--params-file":
                for section, body in _sections(Path(argument)):
                    for name, leaf in flatten(body).items():
                        _check(name, leaf, f" (section {section} of params file {argument})")
            elif option in ("-p", "--param") and ":=" in argument:
                name, _, text = argument.partition(":=")
                _check(name, read_value(name, text, f"-p {name}"), "")
        except ConfigError as exc:
            return str(exc)
    return None


def _sections(path: Path) -> list[tuple[str, dict[str, Any]]]:
    document = read_document(path.read_text(), str(path)) if path.is_file() else None
    if not isinstance(document, dict):
        return []
    return [
        (section, body["ros__parameters"])
        for section, body in document.items()
        if isinstance(body, dict) and isinstance(body.get("ros__parameters"), dict)
    ]


def _check(name: str, leaf: Leaf, source: str) -> None:
    if isinstance(leaf, list) and _mixed([item.value for item in leaf]):
        raise ConfigError(refusal(name, leaf) + source)


# -- writing ---------------------------------------------------------------------------------------------
class _Quoted(str):
    """A string value: written in double quotes, so rcl reads it as text whatever it says."""


class _Dumper(yaml.SafeDumper):
    def ignore_aliases(self, data: Any) -> bool:
        return True  # rcl refuses aliases: every value written out


_Dumper.add_representer(_Quoted, lambda dumper, text: dumper.represent_scalar(_STR_TAG, text, style='"'))
_Dumper.add_representer(list, lambda dumper, items: dumper.represent_sequence(_SEQ_TAG, items, flow_style=True))


def _quoted(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {key: _quoted(v) for key, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_quoted(v) for v in value]
    if isinstance(value, str):
        return _Quoted(value)
    if value is None or not isinstance(value, (bool, int, float)):
        raise TypeError(f"not a parameter value: {value!r}")
    return value


def dump(document: Mapping[str, Any]) -> str:
    """``document`` (node sections of flat parameters) as YAML that rcl reads back with the same
    types: every string quoted, numbers and booleans plain, lists in flow style, no aliases."""
    return yaml.dump(_quoted(document), Dumper=_Dumper, sort_keys=False, width=1000)


def load_params_file(path: str | Path, node_name: str) -> dict[str, Any]:
    """The flat parameters a node named ``node_name`` gets from a ROS 2 params file.

    Sections ``/**`` and ``<node_name>`` (also ``/<node_name>``) are merged in file
    order, as rcl does. Values are read as the node's rcl reads them and given the meaning the
    user wrote (``rcl_yaml``): every reader of a scenario file sees what the nodes will.
    """
    return load_nodes_params(path, [node_name])[node_name]


def load_nodes_params(path: str | Path, node_names: Sequence[str]) -> dict[str, dict[str, Any]]:
    """``load_params_file`` for each of ``node_names``, the file read and parsed once."""
    path = Path(path)
    document = params_document(path)
    return {node: conform_all(sections_of(document, path, node), str(path)) for node in node_names}
