"""A command's Ctrl-C at a known moment: its ``main`` in this process, sent a real SIGINT right after the
n-th call of one of its functions returns (a row saved, a trial told). Which rows a Ctrl-C keeps is then
a count, not a race between a poll of the output directory and the command's pace on a busy machine."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Sequence
from typing import Any

import pytest

from bracing_experiments.executors import STOP_REQUESTED


def main_interrupted_after(
    main: Callable[[Sequence[str]], int],
    argv: Sequence[str],
    monkeypatch: pytest.MonkeyPatch,
    owner: Any,
    name: str,
    calls: int,
) -> tuple[int, list[Any]]:
    """``main(argv)`` with ``owner.name`` wrapped: once its ``calls``-th call has returned, this process
    gets SIGINT (the command's own handler takes it, as it takes a Ctrl-C). The exit code and each call's
    arguments (after the instance, for a method). The process's signal handlers and STOP_REQUESTED are as
    before afterwards (the command installs its own)."""
    real = getattr(owner, name)
    made: list[Any] = []

    def then_ctrl_c(*args: Any, **kwargs: Any) -> Any:
        result = real(*args, **kwargs)
        made.append(args[1:] if isinstance(owner, type) else args)
        if len(made) == calls:
            os.kill(os.getpid(), signal.SIGINT)
        return result

    monkeypatch.setattr(owner, name, then_ctrl_c)
    previous = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        code = main(list(argv))
    finally:
        signal.signal(signal.SIGINT, previous[0])
        signal.signal(signal.SIGTERM, previous[1])
        STOP_REQUESTED.clear()
    return code, made
