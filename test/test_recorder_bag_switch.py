"""bracing-recorder --stay: one recorder, one bag after another (``bracing_recorder.bag_switch``). The same
stream recorded twice, the second time into the bag its ``output`` parameter asked for, gives two bags equal
message for message and byte for byte: what it derives (/tf, /tf_static, the markers) and the robot
description the simulator latched once included."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

from test_recorder_report import CONTACTS, N_STEPS, ROOT, Proc, procs, ros_env, start_publisher, start_recorder

from bracing_analysis.bag_events import custom_data

__all__ = ["procs"]  # the fixture, used by name

PARAMS = str(ROOT / "config" / "paper_4link.yaml")

SET_PARAMETERS = """
import json, sys
import rclpy
from rclpy.parameter import Parameter
from rcl_interfaces.srv import SetParametersAtomically
rclpy.init()
node = rclpy.create_node("bag_switch_test")
client = node.create_client(SetParametersAtomically, "/bracing_recorder_next_bag/set_parameters_atomically")
assert client.wait_for_service(timeout_sec=20.0), "no recorder parameter service"
request = SetParametersAtomically.Request()
request.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in json.loads(sys.argv[1]).items()]
future = client.call_async(request)
rclpy.spin_until_future_complete(node, future, timeout_sec=20.0)
result = future.result().result
print(json.dumps([result.successful, result.reason]))
"""


def set_recorder(env: dict[str, str], values: dict[str, Any]) -> tuple[bool, str]:
    """Set the recorder's parameters in one call (as ``ros2 param load`` would); (successful, reason)."""
    done = subprocess.run(
        [sys.executable, "-c", SET_PARAMETERS, json.dumps(values)], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr[-2000:]
    successful, reason = json.loads(done.stdout.strip().splitlines()[-1])
    return bool(successful), str(reason)


def raw_bag(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    """topic -> [(bag timestamp, CDR bytes)] in the order written."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([bag]) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, [])
        for conn, stamp, data in reader.messages():
            out[conn.topic].append((stamp, bytes(data)))
    return {topic: sorted(messages) for topic, messages in out.items()}


def go(pub: Proc) -> None:
    assert pub.popen.stdin is not None
    pub.popen.stdin.write("go\n")
    pub.popen.stdin.flush()


def test_a_staying_recorder_records_the_next_run_as_a_new_recorder_would(tmp_path: Path, procs: list[Proc]) -> None:
    env = ros_env()
    first, second = tmp_path / "first" / "bag", tmp_path / "second" / "bag"
    stay = ("--stay", "--expect-states", str(N_STEPS), "--params-file", PARAMS, "--scenario", "paper_4link")
    rec = start_recorder(procs, env, first, "", CONTACTS, *stay)
    pub = start_publisher(procs, env, tmp_path, "", CONTACTS, N_STEPS, period=0.0, wait_go=True, runs=2)
    pub.wait_line("matched", timeout=20.0)
    refused = set_recorder(env, {"output": str(second)})  # while the first bag records
    assert refused == (False, "a bag is open: the next opens once it is closed")
    go(pub)
    rec.wait_line("recorder wrote 1601 messages to " + str(first), timeout=60.0)  # 8 per state, the description
    assert rec.popen.poll() is None  # it stays
    assert set_recorder(env, {"output": str(second), "expect_states": N_STEPS}) == (True, "")
    rec.wait_line("recorder ready", timeout=20.0)
    go(pub)
    rec.wait_line("recorder wrote 1601 messages to " + str(second), timeout=60.0)
    rec.popen.send_signal(signal.SIGINT)  # between bags: it ends with none open
    code, err = rec.finish(timeout=20.0)
    assert code == 0, err
    pub.wait_line("published", timeout=20.0)
    one, two = raw_bag(first), raw_bag(second)
    assert len(one["/joint_states"]) == N_STEPS and len(one["/tf"]) == N_STEPS and len(one["/tf_static"]) == 1
    assert len(one["/robot_description"]) == 1
    assert two == one  # every topic, every message: stamps and bytes
    assert custom_data(second) == custom_data(first)  # the scenario, its surfaces, the task's notes
    assert "paper_4link" in json.dumps(custom_data(second))
