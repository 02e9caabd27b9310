"""Where ``bracing-view`` serves (no rerun import: ``bracing-pair`` prints it without loading rerun)."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from urllib.parse import quote

WEB_PORT = 9090
"""The web viewer's HTTP port on 127.0.0.1 (rerun's default)."""
GRPC_PORT = 9876
"""The gRPC proxy the recording streams to, on 127.0.0.1 (rerun's default)."""


def view_url(web_port: int = WEB_PORT, grpc_port: int = GRPC_PORT) -> str:
    """The page to open: the web viewer, told where its data is."""
    return f"http://127.0.0.1:{web_port}/?url={quote(f'rerun+http://127.0.0.1:{grpc_port}/proxy', safe='')}"


def free_ports(count: int = 2) -> list[int]:
    """``count`` ports free on 127.0.0.1 now (the kernel's choice), for a viewer of its own: two
    runs with --view on one machine must not meet on the default ports."""
    sockets = [socket.socket(socket.AF_INET, socket.SOCK_STREAM) for _ in range(count)]
    try:
        for sock in sockets:
            sock.bind(("127.0.0.1", 0))
        return [int(sock.getsockname()[1]) for sock in sockets]
    finally:
        for sock in sockets:
            sock.close()


def wait_for_port(port: int, alive: Callable[[], bool], timeout: float) -> bool:
    """Whether something listens on 127.0.0.1:``port`` within ``timeout`` seconds (False at once
    when ``alive()`` says the process that should open it has ended)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not alive():
            return False
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                return True
        time.sleep(0.1)
    return False
