"""DDS round-trip bound: two rclpy processes in lockstep over Fast DDS.

The upper bound on the lockstep simulator/controller pair's step rate: one process
("ping", playing the simulator) publishes a sensor_msgs/JointState with 4 joints
(names, positions, velocities, efforts) on ``ping`` and waits for the answer; the
other ("pong", playing the controller) answers each message immediately with a
bracing_msgs/MotorCommand with 4 values on ``pong``, stamped with the request's stamp.
Both sides use RELIABLE QoS, depth 10, and a SingleThreadedExecutor driven with
spin_once, like the real lockstep nodes; no computation besides building messages.

Process layout (the parent never imports rclpy):
    parent --spawns--> ``python bench/dds_bound.py pong``
           --runs----> ``python bench/dds_bound.py ping --n N --repeats R --warmup W``
                       (prints one JSON line with the per-repeat round trips/s)
Both children get ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a random
ROS_DOMAIN_ID in [150, 230]. Needs the workspace environment (``source env.sh``)
for bracing_msgs.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time

JOINTS = ("joint1", "joint2", "joint3", "joint4")
PING_TOPIC = "ping"
PONG_TOPIC = "pong"


def _qos():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


# --------------------------------------------------------------------------- pong


def _pong_main() -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    from bracing_msgs.msg import MotorCommand

    parent = os.getppid()
    rclpy.init()
    node = rclpy.create_node("bench_dds_pong")
    pub = node.create_publisher(MotorCommand, PONG_TOPIC, _qos())

    def on_ping(msg: JointState) -> None:
        out = MotorCommand()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = msg.header.frame_id
        out.mode = MotorCommand.VOLTAGE
        out.name = list(msg.name)
        out.value = [0.1, 0.2, 0.3, 0.4]
        pub.publish(out)

    node.create_subscription(JointState, PING_TOPIC, on_ping, _qos())
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        # Exit on its own if the parent goes away (no orphaned pong).
        while rclpy.ok() and os.getppid() == parent:
            executor.spin_once(timeout_sec=0.2)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


# --------------------------------------------------------------------------- ping


def _ping_main(n: int, repeats: int, warmup: int, discovery_timeout: float) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    from bracing_msgs.msg import MotorCommand

    rclpy.init()
    node = rclpy.create_node("bench_dds_ping")
    pub = node.create_publisher(JointState, PING_TOPIC, _qos())
    last = {"sec": -1, "nanosec": -1}

    def on_pong(msg: MotorCommand) -> None:
        last["sec"] = msg.header.stamp.sec
        last["nanosec"] = msg.header.stamp.nanosec

    sub = node.create_subscription(MotorCommand, PONG_TOPIC, on_pong, _qos())
    executor = SingleThreadedExecutor()
    executor.add_node(node)

    def send(sec: int, nanosec: int) -> None:
        # A fresh message per step, as the simulator builds one per step.
        msg = JointState()
        msg.header.stamp.sec = sec
        msg.header.stamp.nanosec = nanosec
        msg.name = list(JOINTS)
        msg.position = [0.1, 0.2, 0.3, 0.4]
        msg.velocity = [0.0, 0.0, 0.0, 0.0]
        msg.effort = [1.0, 2.0, 3.0, 4.0]
        pub.publish(msg)

    def wait_for(sec: int, nanosec: int, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while last["sec"] != sec or last["nanosec"] != nanosec:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return False
            executor.spin_once(timeout_sec=remaining)
        return True

    try:
        # Discovery: both directions matched.
        deadline = time.monotonic() + discovery_timeout
        while pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1:
            if time.monotonic() > deadline:
                raise RuntimeError(f"pong not discovered within {discovery_timeout:.0f} s")
            executor.spin_once(timeout_sec=0.05)

        # Warm-up; the first messages after matching may still be in flight, so resend.
        for i in range(warmup):
            for _attempt in range(20):
                send(0, i)
                if wait_for(0, i, 0.25):
                    break
            else:
                raise RuntimeError("no echo during warm-up")

        samples = []
        for r in range(1, repeats + 1):
            t0 = time.perf_counter()
            for i in range(n):
                send(r, i)
                if not wait_for(r, i, 5.0):
                    raise RuntimeError(f"lost echo (repeat {r}, message {i})")
            samples.append(n / (time.perf_counter() - t0))
        print(json.dumps({"samples": samples}), flush=True)
        return 0
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


# --------------------------------------------------------------------------- parent


def _child_env() -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(random.randint(150, 230))
    env.pop("ROS_STATIC_PEERS", None)
    return env


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=3.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=3.0)


def dds_round_trips_per_s(n: int = 3000, repeats: int = 3, warmup: int = 200, timeout_s: float = 60.0) -> dict:
    """Median (and samples) of lockstep round trips/s between two rclpy processes.

    One round trip = publish a 4-joint JointState, receive the 4-value MotorCommand
    answering it (matched by stamp). Runs the pong and the ping side as subprocesses
    on a private localhost-only DDS domain; both are always cleaned up.
    """
    env = _child_env()
    script = os.path.abspath(__file__)
    with tempfile.TemporaryFile() as pong_err:
        pong = subprocess.Popen(
            [sys.executable, script, "pong"],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=pong_err,
        )
        ping = None
        try:
            ping = subprocess.Popen(
                [
                    sys.executable,
                    script,
                    "ping",
                    f"--n={n}",
                    f"--repeats={repeats}",
                    f"--warmup={warmup}",
                ],
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            try:
                out, err = ping.communicate(timeout=timeout_s)
            except subprocess.TimeoutExpired as exc:
                raise RuntimeError(f"ping side did not finish within {timeout_s} s") from exc
            if ping.returncode != 0:
                pong_err.seek(0)
                raise RuntimeError(
                    f"ping side failed (rc={ping.returncode}): {err.strip()[-2000:]}\n"
                    f"pong stderr: {pong_err.read().decode(errors='replace')[-2000:]}"
                )
            lines = [ln for ln in out.splitlines() if ln.startswith("{")]
            samples = json.loads(lines[-1])["samples"]
        finally:
            if ping is not None:
                _stop(ping)
            _stop(pong)
    return {
        "round_trips_per_s": statistics.median(samples),
        "samples": samples,
        "round_trip_us": 1e6 / statistics.median(samples),
        "n": n,
        "repeats": repeats,
        "warmup": warmup,
        "qos": "RELIABLE, KEEP_LAST 10, VOLATILE",
        "executor": "SingleThreadedExecutor.spin_once",
        "domain_id": int(env["ROS_DOMAIN_ID"]),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("role", nargs="?", choices=("bench", "ping", "pong"), default="bench")
    parser.add_argument("--n", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--discovery-timeout", type=float, default=15.0)
    args = parser.parse_args(argv)
    if args.role == "pong":
        return _pong_main()
    if args.role == "ping":
        return _ping_main(args.n, args.repeats, args.warmup, args.discovery_timeout)
    print(json.dumps(dds_round_trips_per_s(args.n, args.repeats, args.warmup), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
