"""make bench's bound without Python (bench/dds_bound.py, wire rcl: src/bracing_rcl_bench's rcl_pingpong, C++ on
rcl's C API): it runs the round trips asked for, exchanges the pair's own messages byte for byte as the Python
sides do (each side checks every field it receives, across languages both ways), refuses a message not as sent,
and fails with a clear message rather than waiting forever. Nothing here is timed."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from ros_helpers import isolated_env

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT / "bench"))

import dds_bound  # noqa: E402  (bench/ is not a package)

ROUND_TRIPS, REPEATS, WARMUP = 40, 2, 5


@pytest.mark.parametrize(("ping", "pong"), [("rcl", "rcl"), ("rcl", "cdr"), ("cdr", "rcl")])
def test_the_ping_pong_runs_every_round_trip_with_the_messages_as_sent(ping: str, pong: str) -> None:
    # rcl against Python's CDR bytes, both ways: each side decodes the other's messages (Python's decoders
    # check the CDR; rcl_pingpong checks every field, exit status 3 otherwise), so the bytes are the same.
    result = dds_bound.dds_round_trips_per_s(ROUND_TRIPS, REPEATS, WARMUP, timeout_s=120.0, wire=ping, pong_wire=pong)
    assert (result["wire"], result["pong_wire"]) == (ping, pong)
    assert len(result["samples"]) == REPEATS
    assert all(math.isfinite(rate) and rate > 0.0 for rate in result["samples"])
    if ping == "rcl":  # every timed round trip's answer and every warm-up's, each checked field by field
        assert result["checked"] >= ROUND_TRIPS * REPEATS + WARMUP
    else:
        assert result["checked"] is None


def _wrong_state_publisher(domain_env: dict[str, str]) -> subprocess.Popen:
    """A Python process publishing on ``ping`` a JointState whose efforts are not the ping side's."""
    code = (
        "import time, rclpy\n"
        "from sensor_msgs.msg import JointState\n"
        "from bracing_ros.qos import STREAM_QOS\n"
        "rclpy.init(); node = rclpy.create_node('wrong_ping')\n"
        "pub = node.create_publisher(JointState, 'ping', STREAM_QOS)\n"
        "msg = JointState(name=['joint1', 'joint2', 'joint3', 'joint4'], position=[0.1, 0.2, 0.3, 0.4],\n"
        "                 velocity=[0.0] * 4, effort=[1.0, 2.0, 3.0, 5.0])\n"
        "for _ in range(600):\n"
        "    pub.publish(msg); time.sleep(0.05)\n"
    )
    return subprocess.Popen([sys.executable, "-c", code], env=domain_env, stdout=subprocess.DEVNULL)


def test_a_state_not_as_sent_stops_the_pong_side_naming_the_field() -> None:
    env = isolated_env()
    pong = subprocess.Popen([str(dds_bound.rcl_program()), "pong"], env=env, stderr=subprocess.PIPE, text=True)
    wrong = _wrong_state_publisher(env)
    try:
        _, err = pong.communicate(timeout=60)
    finally:
        for proc in (wrong, pong):
            proc.kill()
            proc.wait()
    assert pong.returncode == 3, err
    assert "joint_states effort not as sent" in err


def test_without_a_pong_side_the_ping_side_says_so_and_fails() -> None:
    done = subprocess.run(
        [str(dds_bound.rcl_program()), "ping", "--n=5", "--discovery-timeout=1"],
        env=isolated_env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1
    assert "pong not discovered within 1 s" in done.stderr
    assert done.stdout == ""


@pytest.mark.parametrize("argv", [[], ["serve"], ["ping", "--n=x"], ["ping", "--n=0"], ["pong", "--speed=2"]])
def test_bad_arguments_are_refused_with_a_reason(argv: list[str]) -> None:
    done = subprocess.run([str(dds_bound.rcl_program()), *argv], capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    assert done.stderr.startswith("rcl_pingpong: ")


def test_the_pong_side_ends_cleanly_on_sigterm() -> None:
    pong = subprocess.Popen([str(dds_bound.rcl_program()), "pong"], env=isolated_env(), stderr=subprocess.PIPE)
    try:
        with pytest.raises(subprocess.TimeoutExpired):
            pong.wait(timeout=1.0)  # serving: it waits for states
        pong.terminate()
        assert pong.wait(timeout=10) == 0
    finally:
        pong.kill()
        pong.wait()
