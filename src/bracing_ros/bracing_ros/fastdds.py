"""Which Fast DDS profile the bracing processes (the nodes, the recorder) load.

``fastdds_profile.xml`` keeps every socket on the loopback interface (and shared memory): a run
is reachable from this machine only, whatever ROS_AUTOMATIC_DISCOVERY_RANGE says. (Localhost-only
discovery is not enough: Fast DDS's default transport listens on every interface, and a participant
elsewhere that sent to those ports matched the nodes and could publish a motor_command.)
``fastdds_profile_network.xml`` is the same without that restriction, for
``BRACING_DDS_NETWORK=1`` (``bracing-pair --network``): anyone on the network can then talk to
the nodes; SROS2 (``ROS_SECURITY_KEYSTORE``, ``ROS_SECURITY_ENABLE=true``,
``ROS_SECURITY_STRATEGY=Enforce``) is the way to do that securely.

Loopback means loopback whatever the environment says: a user's own ``FASTRTPS_DEFAULT_PROFILES_FILE``
(or a ``DEFAULT_FASTRTPS_PROFILES.xml`` in the working directory, which Fast DDS also loads) is used only
if it cannot open a socket off the loopback interface (``loopback_problem``); otherwise this process
says why and takes the project's loopback profile instead. With the network asked for, the user's
profile wins.

No rclpy here: bracing-pair reads these names without loading ROS.
"""

from __future__ import annotations

import ipaddress
import os
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

FASTDDS_PROFILE = Path(__file__).with_name("fastdds_profile.xml")
FASTDDS_NETWORK_PROFILE = Path(__file__).with_name("fastdds_profile_network.xml")
NETWORK_ENV = "BRACING_DDS_NETWORK"
"""Set to 1 to open the processes' DDS sockets to the network (bracing-pair --network sets it)."""
PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
RANGE_ENV = "ROS_AUTOMATIC_DISCOVERY_RANGE"
WORKING_DIRECTORY_PROFILE = "DEFAULT_FASTRTPS_PROFILES.xml"
"""Fast DDS (2.14, Jazzy's) loads this file from the working directory after PROFILE_ENV's, unless
SKIP_ENV is 1: its default participant profile would replace ours."""
SKIP_ENV = "SKIP_DEFAULT_XML_FILE"
IP_TRANSPORTS = ("UDPv4", "UDPv6", "TCPv4", "TCPv6")


def network_requested() -> bool:
    return os.environ.get(NETWORK_ENV, "").strip().lower() not in ("", "0", "false", "no")


def fastdds_profile() -> Path:
    """The project's profile for this process: loopback only unless the network was asked for."""
    return FASTDDS_NETWORK_PROFILE if network_requested() else FASTDDS_PROFILE


def use_fastdds_profile() -> str | None:
    """Give this process the project's Fast DDS profile (``fastdds_profile()``), or the user's own
    where it keeps to loopback (or the network was asked for); call before ``rclpy.init``. A profile
    that would open another interface is replaced: the reason is printed to stderr (the process's log
    under bracing-pair) and returned."""
    warning = None
    if network_requested():
        os.environ.setdefault(PROFILE_ENV, str(fastdds_profile()))
        return None
    own = os.environ.get(PROFILE_ENV)
    problem = loopback_problem(Path(own)) if own else None
    if not own or problem:
        os.environ[PROFILE_ENV] = str(FASTDDS_PROFILE)
    if problem:
        warning = (
            f"{PROFILE_ENV}={own} not used: {problem}; this process takes the loopback-only profile "
            f"{FASTDDS_PROFILE} ({NETWORK_ENV}=1, bracing-pair --network, to use your own)"
        )
    local = Path(WORKING_DIRECTORY_PROFILE)
    if local.is_file() and os.environ.get(SKIP_ENV) != "1" and (local_problem := loopback_problem(local)):
        os.environ[SKIP_ENV] = "1"
        warning = (warning + "; " if warning else "") + f"./{WORKING_DIRECTORY_PROFILE} not loaded: {local_problem}"
    if os.environ.get(RANGE_ENV, "").strip().upper() != "OFF":
        # The loopback profile keeps discovery on this machine by itself (its peer is 127.0.0.1, no
        # multicast). rmw_fastrtps's LOCALHOST range adds a UDP transport beside the profile's that
        # opened sockets on 0.0.0.0 and the machine's address (seen with ss): the middleware decides.
        os.environ[RANGE_ENV] = "SYSTEM_DEFAULT"
    if warning:
        print(f"warning: {warning}", file=sys.stderr, flush=True)
    return warning


def loopback_problem(path: Path) -> str | None:
    """Why the Fast DDS profiles file ``path`` could open a socket off the loopback interface, or None.

    Conservative: the default participant profile must replace Fast DDS's built-in transports
    (``useBuiltinTransports`` false: those listen on every interface) with shared memory and IP
    transports allowed loopback addresses alone, and name its discovery locators, all loopback
    (without them Fast DDS opens a multicast socket on 0.0.0.0)."""
    try:
        root = ElementTree.parse(path).getroot()
    except (OSError, ElementTree.ParseError) as exc:
        return f"it cannot be read ({exc})"
    for element in root.iter():  # the profiles' namespace, dropped
        element.tag = element.tag.rsplit("}", 1)[-1]
    participant = next((p for p in root.iter("participant") if p.get("is_default_profile") == "true"), None)
    if participant is None:
        return "it has no default participant profile (Fast DDS's default transports listen on every interface)"
    rtps = participant.find("rtps")
    if rtps is None or (rtps.findtext("useBuiltinTransports") or "").strip().lower() != "false":
        return "its default participant keeps Fast DDS's built-in transports (they listen on every interface)"
    return _transports_problem(root, rtps) or _locators_problem(rtps)


def _transports_problem(root: ElementTree.Element, rtps: ElementTree.Element) -> str | None:
    """Why one of ``rtps``'s user transports may listen off loopback (an IP one without a loopback-only allowlist)."""
    descriptors = {d.findtext("transport_id", "").strip(): d for d in root.iter("transport_descriptor")}
    for transport_id in (t.text.strip() for t in rtps.iterfind("userTransports/transport_id") if t.text):
        descriptor = descriptors.get(transport_id)
        if descriptor is None:
            return f"its transport {transport_id!r} is not described"
        kind = descriptor.findtext("type", "").strip()
        if kind not in IP_TRANSPORTS:
            continue  # shared memory
        allowed = [a.text or "" for a in descriptor.iterfind("interfaceWhiteList/address")]
        allowed += [a.get("name", "") for a in descriptor.iterfind("interfaces/allowlist/interface")]
        if not allowed or not all(_is_loopback(a) for a in allowed):
            return f"its {kind} transport {transport_id!r} is not kept to loopback addresses ({allowed or 'none'})"
    return None


def _locators_problem(rtps: ElementTree.Element) -> str | None:
    """Why ``rtps``'s locators may open a socket off loopback (multicast, another address, or none named)."""
    if rtps.find("builtin/metatrafficUnicastLocatorList") is None:
        return "it names no metatrafficUnicastLocatorList (Fast DDS then opens a multicast socket on 0.0.0.0)"
    for element in rtps.iter():
        if element.tag.endswith("MulticastLocatorList") and len(element):
            return f"it listens on multicast ({element.tag})"
        if element.tag.endswith("UnicastLocatorList"):
            addresses = [a.text or "" for a in element.iter("address")]
            if bad := [a for a in addresses if not _is_loopback(a)]:
                return f"its {element.tag} has addresses off loopback ({bad})"
    return None


def _is_loopback(address: str) -> bool:
    """127.0.0.0/8, ::1 or the interface ``lo``."""
    address = address.strip()
    if address == "lo":
        return True
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:
        return False
