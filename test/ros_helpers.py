"""Helpers for tests that run real ROS 2 processes: DDS isolation and process handling."""

from __future__ import annotations

import os
import random
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def isolated_env(domain_id: int | None = None) -> dict[str, str]:
    """Environment for a child ROS process: localhost-only discovery, a domain of its own.

    Domain ids are drawn per call from 102-232 (the range that bracing-pair does not use
    by default), so two test runs on one machine do not see each other.
    """
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id if domain_id is not None else random.randint(102, 232))
    env["PYTHONUNBUFFERED"] = "1"
    return env


def python(*args: str, env: dict[str, str], **kwargs: object) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        **kwargs,  # type: ignore[call-overload]
    )
