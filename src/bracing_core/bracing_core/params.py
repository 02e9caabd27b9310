"""Flat ROS-style parameters (``"motors.resistance" -> [0.6, ...]``): their type, the error that names a
wrong one, and the configuration files they name.

Both nodes and every in-process user (tests, benchmarks, sweeps) build their typed
configuration from the same flat dict: a node gets it from its ROS parameters, the
library from the scenario YAML (``rcl_yaml.load_params_file``). ``schema.read`` checks and types
them in one pass (every typed read is there); errors name the parameter and what was expected.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

Params = Mapping[str, Any]


class ConfigError(ValueError):
    """An invalid or unknown parameter, or a missing file; the message names it."""


def resolve_file(name: str, parameter: str, search_dirs: Sequence[Path] = ()) -> Path:
    """Find a configuration file: as given, then in the usual config directories; a ``package://NAME/...``
    name in package NAME wherever a URDF's meshes are looked up (``meshes.find_package``)."""
    if name.startswith("package://"):
        from bracing_core.meshes import resolve  # a leaf module: no import cycle

        found = resolve(name)
        if found is None:
            raise ConfigError(
                f"{parameter}: {name!r} not found (the package is looked up in the ament index, ROS_PACKAGE_PATH "
                "and the Python environment's cmeel prefix: is it installed?)"
            )
        return found
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
