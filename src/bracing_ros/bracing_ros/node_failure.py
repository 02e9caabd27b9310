"""An exception that ends a node's run: one raised by its per-state path on rcl (``bracing_rcl``, C++: rcl's
failures as RuntimeError with rcl's message) or any other the node's loop did not expect.

The node says it once, at FATAL in its log, with where it was raised (the path and its topic, ``PathError``; else
the Python function it came through) and its message; gives it on stderr as the line bracing-pair reads for
summary.json's ``error`` (``bracing_core.failures.NODE_FAILED``); flushes what it sent (its subscribers, the
recorder, have what it published before the failure) and exits with ``EXIT_NODE_FAILED``. run_status has no
word for a failure (its WARNING is a warning about a run that goes on), so it is not said there, as a
divergence is not.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Protocol

from bracing_core.failures import EXIT_NODE_FAILED, NODE_FAILED


class Logger(Protocol):
    """What is used of a node's rclpy logger."""

    def fatal(self, message: str) -> object: ...
    def error(self, message: str) -> object: ...


class PathError(RuntimeError):
    """An exception raised by a node's per-state path on rcl (C++), with where: the path and its topic."""

    def __init__(self, where: str, error: Exception) -> None:
        super().__init__(f"{type(error).__name__}: {error}")
        self.where = where


def where_raised(exc: BaseException) -> str:
    """Where ``exc`` was raised: a ``PathError``'s path, else the innermost Python function it came through
    (a C++ call's caller)."""
    if isinstance(exc, PathError):
        return exc.where
    innermost = exc.__traceback__
    if innermost is None:
        return "the node's loop"
    while innermost.tb_next is not None:
        innermost = innermost.tb_next
    frame = innermost.tb_frame
    return f"{frame.f_globals.get('__name__', '?')}.{frame.f_code.co_qualname} (line {innermost.tb_lineno})"


def failure_text(exc: BaseException, at: str = "") -> str:
    """What ended the run: where, ``at`` (e.g. the sim time), the exception's type and message."""
    what = str(exc) if isinstance(exc, PathError) else f"{type(exc).__name__}: {exc}"
    return f"{where_raised(exc)}{at}: {what}"


def end_run(logger: Logger, exc: BaseException, flush: Callable[[], None], at: str = "") -> int:
    """Say ``exc`` (see the module docstring), ``flush`` what the node sent, and the node's exit code."""
    text = failure_text(exc, at)
    logger.fatal(f"the run failed in {text}")
    print(f"{NODE_FAILED}{text}", file=sys.stderr, flush=True)
    try:
        flush()
    except Exception as flush_exc:  # rcl itself may be what failed: the exit still follows
        logger.error(f"flushing after the failure failed too: {type(flush_exc).__name__}: {flush_exc}")
    return EXIT_NODE_FAILED
