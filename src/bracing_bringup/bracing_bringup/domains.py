"""ROS domain ids held exclusively while a run lives, so that two runs on one machine never
see each other.

ROS's own tool for this is ``domain_coordinator`` (launch_testing uses it): an id d is held
by binding the TCP port 32768 + d, which the kernel gives to one socket at a time and takes
back when the process ends, however it ends. Ids come from 1-100, inside the range ROS
documents as safe (0-101: higher ids can collide with ephemeral ports).
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator
from dataclasses import dataclass

import domain_coordinator
from domain_coordinator.impl import PORT_BASE


@dataclass(frozen=True)
class HeldDomain:
    domain_id: int
    exclusive: bool  # False: an id asked for explicitly that another run holds (it is used anyway)


def is_held_elsewhere(domain_id: int) -> bool:
    """Whether another process (a run, a test) holds ``domain_id`` now."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        probe.bind(("", PORT_BASE + domain_id))
    except OSError:
        return True
    finally:
        probe.close()
    return False


@contextlib.contextmanager
def hold_domain(requested: int | None = None) -> Iterator[HeldDomain]:
    """A domain id held by this process until the block ends.

    Without ``requested``: the first free id (domain_coordinator's choice). With it: that
    id, held if nobody else holds it, else used anyway with ``exclusive=False`` (the
    caller says so): an explicit ``--domain-id`` always wins.
    """
    selector = None if requested is None else _only(requested)
    stack = contextlib.ExitStack()
    try:
        domain = stack.enter_context(domain_coordinator.domain_id(selector))
        held = HeldDomain(int(domain), True)
    except RuntimeError:
        if requested is None:
            raise RuntimeError("no free ROS domain id on this machine (1-100 are all held by other runs)") from None
        held = HeldDomain(requested, False)
    try:
        yield held
    finally:
        # Leave domain_coordinator's generator without an exception: it retries the next id on an
        # OSError thrown into it, which would hide the caller's own error.
        stack.close()


def _only(domain_id: int) -> domain_coordinator.impl.default_selector:
    class Only(domain_coordinator.impl.default_selector):
        def __call__(self) -> int:
            return domain_id

    return Only()
