"""A node's ``main()``: start rclpy, build and spin the node, and turn start-up errors into one clear
line and an exit code."""

from __future__ import annotations

import sys
from collections.abc import Callable

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from bracing_core import rcl_yaml
from bracing_core.params import ConfigError
from bracing_ros import stop_signal
from bracing_ros.fastdds import use_fastdds_profile
from bracing_ros.lifetime import report_faults, stop_with_parent

EXIT_CONFIG = 2


def run(node_factory: Callable[[], Node], spin: Callable[[Node], int], args: list[str] | None = None) -> int:
    """Create the node, spin it, and turn start-up errors into one clear line and exit 2."""
    report_faults()  # its stack on a crash, and every thread's on SIGUSR1 (a hang)
    code = 0
    node: Node | None = None
    try:
        try:
            # KeyboardInterrupt on SIGINT and SIGTERM instead of rclpy's handling, which shuts the
            # context down at once: a node stopping must still flush what its subscribers have
            # not acknowledged (see AckWindow), and that needs a live context.
            stop_signal.install()
            stop_with_parent()
            use_fastdds_profile()
            rclpy.init(args=args if args is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
        except RCLError as exc:  # e.g. a params file rcl cannot parse: say which parameter, and the fix
            argv = args if args is not None else sys.argv
            raise ConfigError(rcl_yaml.explain(argv) or str(exc).split(", at /")[0]) from None
        node = node_factory()
        code = spin(node)
    except (ConfigError, ParameterException) as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        code = EXIT_CONFIG
    except (KeyboardInterrupt, ExternalShutdownException):  # stopped: the spin's end, as Ctrl-C
        code = 0
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    return code
