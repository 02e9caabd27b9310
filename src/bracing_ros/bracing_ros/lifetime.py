"""Processes that do not outlive the bracing-pair that started them, and that say where they crashed
or hung (no rclpy needed)."""

from __future__ import annotations

import ctypes
import faulthandler
import os
import signal
import sys

STOP_WITH_PARENT = "BRACING_STOP_WITH_PARENT"
"""Set by bracing-pair to its pid for the processes it starts (see ``stop_with_parent``)."""


def report_faults() -> None:
    """A crash in native code (DDS, pinocchio) leaves this process's Python stack on stderr, and
    ``kill -USR1 PID`` prints every thread's stack (a hang; the tests' run() asks for it at its
    timeout)."""
    faulthandler.enable()
    faulthandler.register(signal.SIGUSR1, all_threads=True)


def stop_with_parent() -> None:
    """Started by bracing-pair (``STOP_WITH_PARENT`` holds its pid): have the kernel send this
    process SIGTERM should the pair die without stopping it (a SIGKILL, a crash). The process
    then stops as on Ctrl-C, closing what it writes, instead of living on in a ROS domain id
    that the next run may be given. Call after installing the SIGTERM handler. Linux only. (The
    kernel's parent-death signal follows the thread that started the process: in bracing-pair,
    the one that then supervises it until it exits.)"""
    parent = os.environ.get(STOP_WITH_PARENT)
    if not parent or not sys.platform.startswith("linux"):
        return
    pr_set_pdeathsig = 1  # <sys/prctl.h>
    ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)
    if str(os.getppid()) != parent:  # the pair died before the request
        os.kill(os.getpid(), signal.SIGTERM)
