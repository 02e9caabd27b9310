"""Whether a node takes its per-message path in C++ on rcl (``bracing_rcl``) or its Python path: the reasons
both nodes share (an environment variable, the message size limit), beside each node's own."""

from __future__ import annotations

import os
from collections.abc import Mapping

from bracing_core.message_limits import MessageLimits, SizeError

PATHS = ("rcl", "python")
"""The values of a node's path variable (BRACING_CONTROLLER_PATH, BRACING_SIMULATOR_PATH); unset: "rcl"."""


def python_only_reasons(env: str, own: Mapping[str, bool], limits: MessageLimits, joints: int) -> str | None:
    """Why the node takes every message on the Python path, comma-separated (None: the rcl path can take them):
    ``env`` set to "python" (or to neither path: said alone), one of the node's ``own`` reasons true, or more
    ``joints`` than ``limits`` let a message name (the Python path refuses such a message by its size)."""
    choice = os.environ.get(env, "rcl")
    if choice not in PATHS:
        return f"{env}={choice!r} is neither of {', '.join(PATHS)}"
    reasons = {f"{env}=python": choice == "python", **own}
    try:
        limits.check_count("name", joints)
    except SizeError:
        reasons["more joints than max_message_elements"] = True
    found = [reason for reason, applies in reasons.items() if applies]
    return ", ".join(found) if found else None
