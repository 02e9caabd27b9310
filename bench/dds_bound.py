"""DDS round-trip bound: two rclpy processes in lockstep, doing what the pair does minus the work.

The upper bound on the lockstep simulator/controller pair's step rate: one process
("ping", playing the simulator) publishes a sensor_msgs/JointState with 4 joints
(names, positions, velocities, efforts) on ``ping`` and waits for the answer; the
other ("pong", playing the controller) answers each message at once with a
bracing_msgs/MotorCommand with 4 values on ``pong``, stamped with the request's stamp.
The transport is the nodes' own: their QoS (bracing_ros.qos STREAM_QOS /
SUBSCRIBE_QOS), their wait (SubscriptionWaiter) and,
with ``--wire cdr``, their CDR bytes (bracing_ros.wire); ``--wire objects`` sends rclpy
message objects instead, for comparison. No computation besides the messages.
``--wire rcl`` is the bound without Python: both sides are src/bracing_rcl_bench's ``rcl_pingpong`` (C++ on
rcl's C API, built by ``make setup``), the same messages on the same topics with the same QoS, each side
checking every field it receives.

Process layout (the parent never imports rclpy):
    parent --spawns--> ``python bench/dds_bound.py pong --wire W`` (rcl: ``rcl_pingpong pong``)
           --runs----> ``python bench/dds_bound.py ping --wire W --n N ...`` (rcl: ``rcl_pingpong ping ...``)
                       (prints one JSON line with the per-repeat round trips/s)
Both children get ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a ROS_DOMAIN_ID that the
parent holds while they live (bracing_bringup.domains). Needs the workspace environment
(``source env.sh``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bracing_bringup.domains import hold_domain

JOINTS = ["joint1", "joint2", "joint3", "joint4"]
PING_TOPIC = "ping"
PONG_TOPIC = "pong"
PYTHON_WIRES = ("cdr", "objects")
WIRES = (*PYTHON_WIRES, "rcl")
RCL_PACKAGE = "bracing_rcl_bench"


class _Side:
    """One end of the ping-pong: a node, its publisher and a SubscriptionWaiter on its input."""

    def __init__(self, name: str, out_type: type, out_topic: str, in_type: type, in_topic: str, wire: str) -> None:
        import rclpy

        from bracing_ros.qos import STREAM_QOS, SUBSCRIBE_QOS
        from bracing_ros.waiter import SubscriptionWaiter

        rclpy.init()
        self.node = rclpy.create_node(name)
        self.pub = self.node.create_publisher(out_type, out_topic, STREAM_QOS)
        self.sub = self.node.create_subscription(in_type, in_topic, _unused, SUBSCRIBE_QOS, raw=wire == "cdr")
        self.waiter = SubscriptionWaiter(self.node, self.sub)

    def close(self) -> None:
        import rclpy

        self.node.destroy_node()
        rclpy.try_shutdown()


def _unused(_: object) -> None:
    raise AssertionError("messages are taken by the SubscriptionWaiter")


# --------------------------------------------------------------------------- pong


def _pong_main(wire_kind: str) -> int:
    import numpy as np
    from rclpy.executors import ExternalShutdownException
    from sensor_msgs.msg import JointState

    from bracing_msgs.msg import MotorCommand
    from bracing_ros import wire

    parent = os.getppid()
    side = _Side("bench_dds_pong", MotorCommand, PONG_TOPIC, JointState, PING_TOPIC, wire_kind)
    encoder = wire.MotorCommandEncoder(JOINTS, MotorCommand.VOLTAGE)
    value = np.array([0.1, 0.2, 0.3, 0.4])

    def answer(msg: object) -> None:
        if wire_kind == "cdr":
            state = wire.decode_joint_state(msg)  # type: ignore[arg-type]
            side.pub.publish(encoder.encode(state.stamp_ns, value))
        else:
            out = MotorCommand(mode=MotorCommand.VOLTAGE, name=list(msg.name), value=value.tolist())  # type: ignore[attr-defined]
            out.header.stamp = msg.header.stamp  # type: ignore[attr-defined]
            side.pub.publish(out)

    try:
        # Exit on its own if the parent goes away (no orphaned pong).
        while os.getppid() == parent:
            for msg in side.waiter.take(0.2):
                answer(msg)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        side.close()
    return 0


# --------------------------------------------------------------------------- ping


def _ping_main(wire_kind: str, n: int, repeats: int, warmup: int, discovery_timeout: float) -> int:
    import numpy as np
    from sensor_msgs.msg import JointState

    from bracing_msgs.msg import MotorCommand
    from bracing_ros import wire

    side = _Side("bench_dds_ping", JointState, PING_TOPIC, MotorCommand, PONG_TOPIC, wire_kind)
    encoder = wire.JointStateEncoder(JOINTS)
    position, velocity, effort = np.array([0.1, 0.2, 0.3, 0.4]), np.zeros(4), np.array([1.0, 2.0, 3.0, 4.0])

    def send(stamp_ns: int) -> None:
        # A fresh message per step, as the simulator sends one per step.
        if wire_kind == "cdr":
            side.pub.publish(encoder.encode(stamp_ns, position, velocity, effort))
            return
        msg = JointState(name=JOINTS, position=position.tolist(), velocity=velocity.tolist(), effort=effort.tolist())
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        side.pub.publish(msg)

    def stamp_of(msg: object) -> int:
        if wire_kind == "cdr":
            return wire.decode_motor_command(msg).stamp_ns  # type: ignore[arg-type]
        return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec  # type: ignore[attr-defined]

    def wait_for(stamp_ns: int, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return False
            if any(stamp_of(msg) == stamp_ns for msg in side.waiter.take(remaining)):
                return True

    try:
        # Discovery: both directions matched.
        deadline = time.monotonic() + discovery_timeout
        while side.pub.get_subscription_count() < 1 or side.sub.get_publisher_count() < 1:
            if time.monotonic() > deadline:
                raise RuntimeError(f"pong not discovered within {discovery_timeout:.0f} s")
            time.sleep(0.05)
        # Warm-up; the first messages after matching may still be in flight, so resend.
        for i in range(warmup):
            for _attempt in range(20):
                send(i)
                if wait_for(i, 0.25):
                    break
            else:
                raise RuntimeError("no echo during warm-up")
        samples = []
        for r in range(1, repeats + 1):
            t0 = time.perf_counter()
            for i in range(n):
                stamp = (r * 1_000_000 + i) * 1_000_000
                send(stamp)
                if not wait_for(stamp, 5.0):
                    raise RuntimeError(f"lost echo (repeat {r}, message {i})")
            samples.append(n / (time.perf_counter() - t0))
        print(json.dumps({"samples": samples}), flush=True)
        return 0
    finally:
        side.close()


# --------------------------------------------------------------------------- parent


def rcl_program() -> Path:
    """The C++ side (``rcl_pingpong`` of src/bracing_rcl_bench, installed by ``make setup``)."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        program = Path(get_package_prefix(RCL_PACKAGE)) / "lib" / RCL_PACKAGE / "rcl_pingpong"
    except PackageNotFoundError:
        raise RuntimeError(f"{RCL_PACKAGE} is not built: run make setup, then source env.sh") from None
    if not program.is_file():
        raise RuntimeError(f"{program} is missing: run make setup (its colcon build installs it)")
    return program


def side_argv(role: str, wire: str, options: list[str]) -> list[str]:
    """The command line of one side (``role`` ping or pong) over ``wire``, with ``options`` (--name=value)."""
    if wire == "rcl":
        return [str(rcl_program()), role, *options]
    return [sys.executable, os.path.abspath(__file__), role, f"--wire={wire}", *options]


def _child_env(domain_id: int) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id)
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


def dds_round_trips_per_s(
    n: int = 3000,
    repeats: int = 3,
    warmup: int = 200,
    timeout_s: float = 120.0,
    wire: str = "cdr",
    pong_wire: str | None = None,
) -> dict:
    """Median (and samples) of lockstep round trips/s between two processes: rclpy's (``wire`` cdr or
    objects) or rcl_pingpong's (rcl, no Python).

    One round trip = publish a 4-joint JointState, receive the 4-value MotorCommand
    answering it (matched by stamp). Runs the pong and the ping side as subprocesses
    on a private localhost-only DDS domain; both are always cleaned up. ``pong_wire``: the pong
    side's wire if not ``wire`` (a C++ side against a Python one: the same bytes on the wire).
    """
    sides = (wire, wire if pong_wire is None else pong_wire)
    with hold_domain() as domain:  # held while the two processes live (bracing_bringup.domains)
        return _round_trips(_child_env(domain.domain_id), n, repeats, warmup, timeout_s, sides)


def _round_trips(
    env: dict[str, str], n: int, repeats: int, warmup: int, timeout_s: float, sides: tuple[str, str]
) -> dict:
    wire, pong_wire = sides
    with tempfile.TemporaryFile() as pong_err:
        pong = subprocess.Popen(
            side_argv("pong", pong_wire, []),
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=pong_err,
        )
        ping = None
        try:
            ping = subprocess.Popen(
                side_argv("ping", wire, [f"--n={n}", f"--repeats={repeats}", f"--warmup={warmup}"]),
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
            if not lines:
                raise RuntimeError(f"ping side printed no result: {out.strip()[-2000:]} {err.strip()[-2000:]}")
            printed = json.loads(lines[-1])
            samples = printed["samples"]
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
        "wire": wire,
        "pong_wire": pong_wire,
        "qos": "the nodes' (bracing_ros.qos STREAM_QOS publishers, SUBSCRIBE_QOS subscriptions)",
        "wait": "rcl_wait on the subscription" if wire == "rcl" else "bracing_ros.waiter.SubscriptionWaiter",
        "checked": printed.get("checked"),  # rcl_pingpong's ping: answers received, every field as sent
        "domain_id": int(env["ROS_DOMAIN_ID"]),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("role", nargs="?", choices=("bench", "ping", "pong"), default="bench")
    parser.add_argument("--n", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--discovery-timeout", type=float, default=15.0)
    parser.add_argument("--wire", choices=WIRES, default="cdr")
    args = parser.parse_args(argv)
    if args.role != "bench" and args.wire not in PYTHON_WIRES:
        parser.error(
            f"this script's sides are Python's ({', '.join(PYTHON_WIRES)}); rcl's: {RCL_PACKAGE}'s rcl_pingpong"
        )
    if args.role == "pong":
        return _pong_main(args.wire)
    if args.role == "ping":
        return _ping_main(args.wire, args.n, args.repeats, args.warmup, args.discovery_timeout)
    result = dds_round_trips_per_s(args.n, args.repeats, args.warmup, wire=args.wire)
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
