"""Test-only fault injection, for test_node_failures alone (which puts this directory on PYTHONPATH): a node's
per-state path on rcl (``bracing_rcl``, C++) given an invalid rcl handle after its first calls, through the
module's public API, so that the real C++ path meets a real rcl error in the running node of a real run.

``BRACING_TEST_FAULT="<module>:<messages>"``: in the process started as ``python -m <module>`` (the run's other
processes are left alone), the path the node built takes its first ``messages`` messages (``CommandPath.take``:
commands, ``ControllerPath.serve``: states); then one built alike but with a null handle takes over: the
simulator's motor_command subscription (rcl_take_serialized_message: "subscription pointer is invalid"), the
controller's motor_command publisher (rcl_publish_serialized_message: "publisher pointer is invalid", once it has
taken a state and run the law). rcl checks both handles before using them: nothing is read from a null pointer.
"""

from __future__ import annotations

import os
import sys
from typing import Any

FAULT_ENV = "BRACING_TEST_FAULT"
FAILING = {"bracing_sim.node": ("CommandPath", "take", 1), "bracing_controller.node": ("ControllerPath", "serve", 5)}
"""Per node module: the path's class, its method that takes messages, the argument made a null handle."""


def taken(result: Any) -> int:
    """How many messages a take (a CommandTake) or a serve (a Served) took."""
    outcomes = getattr(result, "outcomes", None)
    return len(outcomes) if outcomes is not None else int(result.status.name != "empty")


class SwitchedPath:
    """A path whose ``method`` goes to ``real`` until it has taken ``messages``, then to ``failing``."""

    def __init__(self, real: Any, failing: Any, method: str, messages: int) -> None:
        self.real, self.failing, self.method, self.left = real, failing, method, messages

    def __getattr__(self, name: str) -> Any:
        if name != self.method:
            return getattr(self.real, name)
        if self.left <= 0:
            return getattr(self.failing, name)
        real = getattr(self.real, name)

        def counted(*args: Any, **kwargs: Any) -> Any:
            result = real(*args, **kwargs)
            self.left -= taken(result)
            return result

        return counted


def install(module: str, messages: int) -> None:
    import bracing_rcl  # rclpy first, as the node imports it

    cls_name, method, null_argument = FAILING[module]
    real_cls = getattr(bracing_rcl, cls_name)

    def build(*args: Any, **kwargs: Any) -> SwitchedPath:
        broken = list(args)
        broken[null_argument] = 0
        return SwitchedPath(real_cls(*args, **kwargs), real_cls(*broken, **kwargs), method, messages)

    setattr(bracing_rcl, cls_name, build)


_module, _, _messages = os.environ.get(FAULT_ENV, "").partition(":")
if _module in FAILING and sys.orig_argv[1:3] == ["-m", _module]:
    install(_module, int(_messages))
