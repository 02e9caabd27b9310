"""One QoS table: every profile the nodes publish or subscribe with is bracing_ros.qos's, and each
topic role keeps the QoS it has always had (ROS 2's conventions: latched robot_description, reliable
volatile commands, best-effort joint_states from ros2_control)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy, qos_profile_system_default

from bracing_ros import qos

SRC = Path(__file__).resolve().parents[1] / "src"
TABLE = SRC / "bracing_ros" / "bracing_ros" / "qos.py"
RELIABLE, BEST_EFFORT = ReliabilityPolicy.RELIABLE, ReliabilityPolicy.BEST_EFFORT
LATCHED, VOLATILE = DurabilityPolicy.TRANSIENT_LOCAL, DurabilityPolicy.VOLATILE

EXPECTED = {
    "STREAM_QOS": (10000, RELIABLE, LATCHED),
    "SUBSCRIBE_QOS": (2000, RELIABLE, VOLATILE),
    "DESCRIPTION_QOS": (1, RELIABLE, LATCHED),
    "COMMAND_QOS": (10, RELIABLE, VOLATILE),
    "JOINT_STATE_QOS": (10, BEST_EFFORT, VOLATILE),
    "TARGET_QOS": (1, RELIABLE, VOLATILE),
    "ECHO_QOS": (100, RELIABLE, VOLATILE),
    "STATUS_QOS": (100, RELIABLE, LATCHED),
    "RECORD_BATCH_QOS": (100, RELIABLE, LATCHED),
    "RECORD_QOS": (100000, RELIABLE, LATCHED),
    "PARAMETER_EVENTS_QOS": (1000, RELIABLE, VOLATILE),
    "VIEW_QOS": (100, BEST_EFFORT, VOLATILE),
}
"""(depth, reliability, durability) of each role, as the nodes had them before the table gathered them."""


def _sources() -> list[Path]:
    return [p for p in sorted(SRC.rglob("*.py")) if p != TABLE and "/build/" not in str(p)]


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_role_keeps_its_qos(name: str) -> None:
    profile = getattr(qos, name)
    assert (profile.depth, profile.reliability, profile.durability) == EXPECTED[name]
    assert profile.history == HistoryPolicy.KEEP_LAST


def test_the_table_holds_every_profile() -> None:
    assert {n for n in dir(qos) if n.endswith("_QOS")} == {*EXPECTED, "CMD_VEL_QOS"}
    assert qos.CMD_VEL_QOS == qos_profile_system_default  # as diff_drive_controller subscribes cmd_vel


def test_no_profile_is_made_outside_the_table() -> None:
    """No QoSProfile built, no preset taken and no *_QOS defined anywhere in src/ but bracing_ros.qos."""
    offenders = []
    for path in _sources():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) == "QoSProfile":
                offenders.append(f"{path}:{node.lineno} QoSProfile(...)")
            if isinstance(node, ast.Name) and node.id.startswith(("qos_profile_", "QoSPresetProfiles")):
                offenders.append(f"{path}:{node.lineno} {node.id}")
            if isinstance(node, ast.Assign | ast.AnnAssign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    if isinstance(t, ast.Name) and t.id.endswith("_QOS"):
                        offenders.append(f"{path}:{node.lineno} {t.id} defined here")
    assert offenders == []


def test_every_qos_name_used_comes_from_the_table() -> None:
    """A *_QOS name used in src/ is imported from bracing_ros.qos, not from a module that re-exports one."""
    offenders = []
    for path in _sources():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module != "bracing_ros.qos":
                offenders += [f"{path}: {a.name} from {node.module}" for a in node.names if a.name.endswith("_QOS")]
    assert offenders == []
