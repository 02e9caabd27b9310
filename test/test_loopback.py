"""A run is reachable from this machine only: every DDS socket of its processes is
on 127.0.0.1 (and shared memory), and a participant in another network namespace, joined to this
one by a veth pair and told this machine's address there, can neither discover the run nor inject a
command, while the run itself is unaffected. With ``--network`` the same participant does both
(which shows the namespace reaches the run when the sockets are open).

The namespace tests need root and iproute2's ``ip`` (CI has both, and sets BRACING_REQUIRE_NETNS
so that they fail rather than skip). The other side gets a /dev/shm of its own: a machine elsewhere
shares no memory with this one. Only addresses of the veth pair made here are used, the peer's
traffic stops after its run (or ``PEER_SECONDS``), and the namespace is removed after the test.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from ros_helpers import hold_test_domain, isolated_env, pair_argv, start

from bracing_analysis.bag import read_series
from bracing_ros.fastdds import FASTDDS_PROFILE, PROFILE_ENV

PEER = str(REPO_ROOT / "test" / "netns_peer.py")
PEER_SECONDS = 60.0  # its upper bound; it is stopped as soon as the run ends
JOINTS = "joint1,joint2,joint3,joint4"
RUN_S = "3"
STATES = 3001  # a 3 s lockstep run at 1 ms, its first state included


def udp_sockets(pid: int) -> list[str]:
    """``address:port`` of every UDP socket process ``pid`` holds (from /proc, as ss shows them)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    for table in ("udp", "udp6"):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            if fields[9] in inodes:
                found.append(_address(fields[1]))
    return found


def _address(hex_address: str) -> str:
    address, port = hex_address.split(":")
    if len(address) == 8:  # IPv4, little-endian
        octets = [str(int(address[i : i + 2], 16)) for i in range(6, -1, -2)]
        return f"{'.'.join(octets)}:{int(port, 16)}"
    return f"[{address}]:{int(port, 16)}"


def run_processes(output: Path) -> list[int]:
    """The pids of a run's processes (bracing-pair, whose participant follows run_status, the nodes
    and the recorder: their command lines name its output)."""
    pids = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmdline = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if str(output) in cmdline:
            pids.append(int(proc.name))
    return pids


def wait_for_stepping(output: Path, timeout: float = 60.0) -> None:
    log = output / "logs" / "simulator.log"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if log.exists() and "progress t=" in log.read_text(errors="replace"):
            return
        time.sleep(0.05)
    raise AssertionError("the run never stepped")


# A profile a user may export: Fast DDS's default transports (every interface), a faster heartbeat.
OPEN_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <data_writer profile_name="fast_heartbeat_writer" is_default_profile="true">
    <times><heartbeatPeriod><sec>0</sec><nanosec>20000000</nanosec></heartbeatPeriod></times>
  </data_writer>
</profiles>
"""


def exported_profile(which: str, tmp_path: Path) -> dict[str, str]:
    """The environment a shell may hand a run: nothing, the project's own loopback profile exported (as
    an earlier by-hand tutorial suggested), or a profile of the user's that opens every interface."""
    if which == "none":
        return {}
    if which == "project":
        return {PROFILE_ENV: str(FASTDDS_PROFILE)}
    path = tmp_path / "open.xml"
    path.write_text(OPEN_PROFILE)
    return {PROFILE_ENV: str(path)}


@pytest.mark.parametrize("profile", ["none", "project", "open"])
def test_every_socket_of_a_run_is_on_loopback(tmp_path: Path, profile: str) -> None:
    """Whatever Fast DDS profile the shell exports: an open one is replaced, with a warning that says why."""
    output = tmp_path / "run"
    env = isolated_env(**exported_profile(profile, tmp_path))
    proc = start(pair_argv(output, "--duration", RUN_S, "--no-animation"), env)
    try:
        wait_for_stepping(output)
        pids = run_processes(output)
        sockets = {pid: udp_sockets(pid) for pid in pids}
        out = proc.communicate(timeout=120)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, out
    assert len(pids) == 4, pids  # bracing-pair, the simulator, the controller, the recorder
    assert all(sockets.values()), sockets  # each has its DDS sockets
    assert [s for found in sockets.values() for s in found if not s.startswith("127.0.0.1:")] == []
    logs = {name: (output / "logs" / f"{name}.log").read_text() for name in ("simulator", "controller", "recorder")}
    warned = [name for name, text in {"pair": out, **logs}.items() if f"{PROFILE_ENV}=" in text and "not used" in text]
    assert warned == (["pair", "simulator", "controller", "recorder"] if profile == "open" else []), (warned, out)


# -- from another network namespace ------------------------------------------------------------------
@dataclass(frozen=True)
class OtherSide:
    namespace: str
    host_address: str  # this machine's address on the veth pair


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=30)


def _free_subnet() -> int:
    """A 10.231.N.0/30 no interface of this machine uses yet (the pair's two addresses)."""
    used = subprocess.run(["ip", "-4", "-o", "addr"], capture_output=True, text=True, check=True).stdout
    for n in [os.getpid() % 250, *range(250)]:
        if f"10.231.{n}." not in used:
            return n
    raise AssertionError("no free 10.231.N.0/30")


@pytest.fixture
def other_side() -> Iterator[OtherSide]:
    """A network namespace joined to this one by a veth pair (this side 10.231.N.1, that side .2)."""
    if os.geteuid() != 0 or shutil.which("ip") is None:
        reason = "needs root and iproute2's ip (network namespaces)"
        if os.environ.get("BRACING_REQUIRE_NETNS"):
            pytest.fail(reason)
        pytest.skip(reason)
    tag = f"{os.getpid() % 100000}"
    namespace, here, there = f"bracing-peer-{tag}", f"vbh{tag}", f"vbp{tag}"
    n = _free_subnet()
    _ip("netns", "add", namespace)
    try:
        _ip("link", "add", here, "type", "veth", "peer", "name", there, "netns", namespace)
        _ip("addr", "add", f"10.231.{n}.1/30", "dev", here)
        _ip("link", "set", here, "up")
        _ip("-n", namespace, "addr", "add", f"10.231.{n}.2/30", "dev", there)
        _ip("-n", namespace, "link", "set", there, "up")
        _ip("-n", namespace, "link", "set", "lo", "up")
        yield OtherSide(namespace, f"10.231.{n}.1")
    finally:
        subprocess.run(["ip", "netns", "del", namespace], capture_output=True)  # takes the veth pair with it
        subprocess.run(["ip", "link", "del", here], capture_output=True)


# Fast DDS's defaults but for the announcements: every 50 ms for 10 s instead of 5 and then every 3 s,
# so that the peer knocks all through the run, whenever it starts.
PEER_PROFILE = """<?xml version="1.0" encoding="UTF-8"?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <participant profile_name="peer" is_default_profile="true"><rtps><builtin><discovery_config>
    <initialAnnouncements><count>200</count><period><sec>0</sec><nanosec>50000000</nanosec></period>
    </initialAnnouncements>
  </discovery_config></builtin></rtps></participant>
</profiles>
"""


def start_peer(side: OtherSide, domain: int, tmp_path: Path) -> subprocess.Popen[str]:
    """The participant on the other side: this machine's address as its peer, a /dev/shm of its own
    (``ip netns exec`` gives it a mount namespace of its own)."""
    profile = tmp_path / "peer.xml"
    profile.write_text(PEER_PROFILE)
    env = {k: v for k, v in os.environ.items() if k != "BRACING_DDS_NETWORK"}
    env.update(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_STATIC_PEERS=side.host_address,
        FASTRTPS_DEFAULT_PROFILES_FILE=str(profile),
        PYTHONUNBUFFERED="1",
    )
    peer = f"mount -t tmpfs tmpfs /dev/shm && exec {sys.executable} {PEER} --seconds {PEER_SECONDS} --joints {JOINTS}"
    proc = subprocess.Popen(
        ["ip", "netns", "exec", side.namespace, "sh", "-c", peer],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.strip() == "ready", line + proc.stdout.read()
    return proc


def run_beside_peer(tmp_path: Path, side: OtherSide, *extra: str) -> tuple[int, str, dict[str, object], Path]:
    """A 3 s pair run while the peer tries: (exit code, its output, what the peer saw, the run's dir)."""
    domain = hold_test_domain()
    peer = start_peer(side, domain, tmp_path)
    output = tmp_path / "run"
    try:
        done = subprocess.run(
            [*pair_argv(output, "--duration", RUN_S, "--no-animation", "--domain-id", str(domain)), *extra],
            env=isolated_env(domain),
            capture_output=True,
            text=True,
            timeout=240,
            cwd=REPO_ROOT,
        )
    finally:
        peer.send_signal(2)  # SIGINT: it reports what it saw and exits
        seen_text = peer.communicate(timeout=60)[0]
    seen = json.loads(seen_text.strip().splitlines()[-1])
    return done.returncode, done.stdout + done.stderr, seen, output


def test_a_participant_on_the_other_side_can_neither_discover_nor_inject(tmp_path: Path, other_side: OtherSide) -> None:
    code, out, seen, output = run_beside_peer(tmp_path, other_side)
    assert code == 0, out
    assert seen == {"matched": 0, "joint_states": 0, "nodes": ["intruder"]}
    counts = read_series(output / "bag").topic_counts  # the run as alone: every step, no command of the peer's
    assert counts["/joint_states"] == counts["/motor_command"] == STATES
    assert "motor_command rejected" not in (output / "logs" / "simulator.log").read_text()


def test_with_network_the_other_side_reaches_the_run(tmp_path: Path, other_side: OtherSide) -> None:
    """The same namespace, with the sockets opened (``--network``): the peer discovers the run and
    its commands reach the simulator, which rejects them (their stamp answers no state). (The run
    may then fail its bag check: the recorder counted the peer's commands as the controller's.)"""
    _, out, seen, output = run_beside_peer(tmp_path, other_side, "--network")
    assert isinstance(seen["matched"], int) and seen["matched"] >= 1, (seen, out)  # the simulator, the recorder
    assert isinstance(seen["joint_states"], int) and seen["joint_states"] > 0
    assert isinstance(seen["nodes"], list) and "bracing_simulator" in seen["nodes"]
    assert "motor_command rejected: stamp 12345.000000 s" in (output / "logs" / "simulator.log").read_text()
