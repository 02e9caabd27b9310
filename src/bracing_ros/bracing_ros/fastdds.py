"""Which Fast DDS profile the bracing processes (the nodes, the recorder) load.

``fastdds_profile.xml`` keeps every socket on the loopback interface (and shared memory): a run
is reachable from this machine only, whatever ROS_AUTOMATIC_DISCOVERY_RANGE says. (Localhost-only
discovery is not enough: Fast DDS's default transport listens on every interface, and a participant
elsewhere that sent to those ports matched the nodes and could publish a motor_command.)
``fastdds_profile_network.xml`` is the same without that restriction, for
``BRACING_DDS_NETWORK=1`` (``bracing-pair --network``): anyone on the network can then talk to
the nodes; SROS2 (``ROS_SECURITY_KEYSTORE``, ``ROS_SECURITY_ENABLE=true``,
``ROS_SECURITY_STRATEGY=Enforce``) is the way to do that securely. A user's own
``FASTRTPS_DEFAULT_PROFILES_FILE`` wins over both.

No rclpy here: bracing-pair reads these names without loading ROS.
"""

from __future__ import annotations

import os
from pathlib import Path

FASTDDS_PROFILE = Path(__file__).with_name("fastdds_profile.xml")
FASTDDS_NETWORK_PROFILE = Path(__file__).with_name("fastdds_profile_network.xml")
NETWORK_ENV = "BRACING_DDS_NETWORK"
"""Set to 1 to open the processes' DDS sockets to the network (bracing-pair --network sets it)."""
PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
RANGE_ENV = "ROS_AUTOMATIC_DISCOVERY_RANGE"


def network_requested() -> bool:
    return os.environ.get(NETWORK_ENV, "").strip().lower() not in ("", "0", "false", "no")


def fastdds_profile() -> Path:
    """The project's profile for this process: loopback only unless the network was asked for."""
    return FASTDDS_NETWORK_PROFILE if network_requested() else FASTDDS_PROFILE


def use_fastdds_profile() -> None:
    """Give this process the project's Fast DDS profile (``fastdds_profile()``) unless the user
    chose a profile file. Call before ``rclpy.init``."""
    if PROFILE_ENV in os.environ:
        return  # the user's own profile: theirs to configure
    os.environ[PROFILE_ENV] = str(fastdds_profile())
    if not network_requested() and os.environ.get(RANGE_ENV, "").strip().upper() != "OFF":
        # The loopback profile keeps discovery on this machine by itself (its peer is 127.0.0.1, no
        # multicast). rmw_fastrtps's LOCALHOST range adds a UDP transport beside the profile's that
        # opened sockets on 0.0.0.0 and the machine's address (seen with ss): the middleware decides.
        os.environ[RANGE_ENV] = "SYSTEM_DEFAULT"
