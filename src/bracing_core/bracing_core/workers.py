"""Worker processes of a pool (bracing-sweep's runs, the report's drawings)."""

from __future__ import annotations

import signal


def ignore_sigint() -> None:
    """A worker's initializer: Ctrl-C reaches the whole process group, and the parent decides what stops
    (it stops the pool itself); a worker must not die mid-task and break the pool."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
