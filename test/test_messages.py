"""bracing_msgs: real rosidl messages travel intact between two OS processes over DDS."""

from __future__ import annotations

import json
import subprocess
import sys

from ros_helpers import REPO_ROOT, isolated_env

ECHO = str(REPO_ROOT / "test" / "msg_echo.py")


def test_every_message_crosses_processes_intact() -> None:
    env = isolated_env()
    sender = subprocess.Popen(
        [sys.executable, ECHO, "send"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    try:
        receiver = subprocess.run(
            [sys.executable, ECHO, "receive"], env=env, capture_output=True, text=True, timeout=60
        )
    finally:
        sender.terminate()
        sender.wait(10)
    assert receiver.returncode == 0, receiver.stderr
    result = json.loads(receiver.stdout.strip().splitlines()[-1])
    assert (
        sorted(result["received"])
        == sorted(result["expected"])
        == sorted(["MotorCommand", "MotorState", "Contacts", "ControllerState", "ContactState"])
    )
    assert result["received"] == result["expected"]
    assert result["received"]["MotorCommand"]["mode"] == 1
    assert result["received"]["Contacts"]["contacts"][1]["active"] is False


def test_motor_command_constants() -> None:
    from bracing_msgs.msg import MotorCommand

    assert MotorCommand.VOLTAGE == 0
    assert MotorCommand.TORQUE == 1
    assert MotorCommand().mode == MotorCommand.VOLTAGE  # default: voltage


def test_two_domains_do_not_see_each_other() -> None:
    """The isolation the tests rely on: a sender in another domain is not received."""
    sender = subprocess.Popen(
        [sys.executable, ECHO, "send"], env=isolated_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        env = isolated_env()
        receiver = subprocess.run(
            [sys.executable, ECHO, "receive", "4"], env=env, capture_output=True, text=True, timeout=60
        )
    finally:
        sender.terminate()
        sender.wait(10)
    assert json.loads(receiver.stdout.strip().splitlines()[-1])["received"] == {}
