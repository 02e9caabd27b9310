"""Flat ROS-style parameters (``"motors.resistance" -> [0.6, ...]``) and their validation.

Both nodes and every in-process user (tests, benchmarks, sweeps) build their typed
configuration from the same flat dict: a node gets it from its ROS parameters, the
library from the scenario YAML (``rcl_yaml.load_params_file``). Errors name the parameter and
what was expected.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from bracing_core.numbers import number

Params = Mapping[str, Any]


class ConfigError(ValueError):
    """An invalid or unknown parameter, or a missing file; the message names it."""


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


# -- typed reads ------------------------------------------------------------------------
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


def get_floats(
    params: Params,
    name: str,
    default: Sequence[float] | None = None,
    *,
    length: int | None = None,
    length_hint: str = "",
) -> tuple[float, ...]:
    """A list of finite numbers; an empty or unset list reads as ``()``."""
    value = params.get(name, default)
    if value is None:
        value = []
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value]
    if not isinstance(value, (list, tuple)) or not all(number(v) for v in value):
        raise ConfigError(f"{name}: expected a list of finite numbers, got {value!r}")
    if length is not None and len(value) != length:
        hint = f" ({length_hint})" if length_hint else ""
        raise ConfigError(f"{name}: expected {length} values{hint}, got {len(value)}")
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


def resolve_file(name: str, parameter: str, search_dirs: Sequence[Path] = ()) -> Path:
    """Find a configuration file: as given, then in the usual config directories."""
    path = Path(name).expanduser()
    if path.is_absolute():
        if path.is_file():
            return path
        raise ConfigError(f"{parameter}: file not found: {path}")
    candidates = [Path.cwd() / path, *(Path(d) / path for d in search_dirs)]
    root = os.environ.get("BRACING_ROOT")
    if root:
        candidates.append(Path(root) / "config" / path)
    try:
        from ament_index_python.packages import get_package_share_directory

        candidates.append(Path(get_package_share_directory("bracing_bringup")) / "config" / path)
    except Exception:  # not in a ROS workspace: the other places still count
        pass
    for candidate in candidates:
        if candidate.is_file():
            return candidate.resolve()
    tried = ", ".join(str(c) for c in candidates)
    raise ConfigError(f"{parameter}: file {name!r} not found (looked in: {tried})")
