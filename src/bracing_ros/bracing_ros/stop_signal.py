"""A stop signal (SIGINT, SIGTERM) as a KeyboardInterrupt, even where rclpy loses it.

The nodes stop on KeyboardInterrupt (``node_main.run`` installs ``request_stop`` for both signals), so
that a stopping node can still flush what its subscribers have not acknowledged. Python runs a signal
handler between bytecodes; when that is inside rclpy's conversion of a taken message to its Python
class (a subscription that is not raw), pybind11 replaces the KeyboardInterrupt with ``RuntimeError:
Unable to convert call argument '0' to Python object``, and the node ended with that traceback (about
1 Ctrl-C in 10 under a 5 kHz flood). Where rclpy takes messages (``StoppableExecutor``, the waiter)
such a RuntimeError after a stop signal is the KeyboardInterrupt again.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from typing import TypeVar

from rclpy.executors import SingleThreadedExecutor

T = TypeVar("T")

_requested = False  # a stop signal has come (never reset: the process is ending)
_held = False  # inside ``held``: a stop signal waits for its end
_pending = False  # a stop signal came inside ``held``


def request_stop(signum: int, frame: object) -> None:
    """The handler of SIGINT and SIGTERM: the process is to stop (``KeyboardInterrupt``; inside ``held``, at
    its end)."""
    global _requested, _pending
    _requested = True
    if _held:
        _pending = True
        return
    raise KeyboardInterrupt()


class _Held:
    def __enter__(self) -> None:
        global _held
        _held = True

    def __exit__(self, *exc: object) -> None:
        global _held, _pending
        _held = False
        if _pending:
            _pending = False
            raise KeyboardInterrupt()


held = _Held()
"""``with held:`` a few steps that must not be cut apart by a stop signal (a message published and its copy
kept for the recorder): its KeyboardInterrupt comes at the end of the block. Never around a wait."""


def raise_if_requested() -> None:
    """KeyboardInterrupt if a stop signal has come: a wait that outlives one (its KeyboardInterrupt lost in a
    library, as above) still ends at its next round."""
    if _requested:
        raise KeyboardInterrupt()


def install() -> None:
    """``request_stop`` for SIGINT and SIGTERM (also when started with SIGINT ignored: bracing-pair
    stops the nodes with it; seen: the controller of a backgrounded make bench ignored it)."""
    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)


def taking(take: Callable[[], T]) -> T:
    """``take()`` (rclpy taking messages); a RuntimeError after a stop signal is raised as the
    KeyboardInterrupt it replaced."""
    try:
        return take()
    except RuntimeError:
        if _requested:
            raise KeyboardInterrupt() from None
        raise


class StoppableExecutor(SingleThreadedExecutor):
    """rclpy's single-threaded executor whose ``spin_once`` stops with KeyboardInterrupt on a stop signal
    (see the module docstring)."""

    def spin_once(self, timeout_sec: float | None = None) -> None:
        taking(lambda: super(StoppableExecutor, self).spin_once(timeout_sec=timeout_sec))
