"""The rosbags typestore of the bracing interface: ROS 2 Jazzy's types plus bracing_msgs.

The recorder writes bags with it (definitions embedded), ``bracing_ros.wire`` derives message
bytes from its field definitions (through :mod:`bracing_core.cdr`) and the analysis reads the
``.msg`` constants from it, so a ``.msg`` file is the one place a message's layout is written.
No ROS: it lives here for the ROS-free analysis as much as for the nodes.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

BRACING_MSGS = ("ContactState", "Contacts", "ControllerState", "MotorCommand", "MotorState", "RecordBatch", "RunStatus")

# The message types a run sends, records and derives, named as the typestore and a bag's metadata name them.
JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
CLOCK = "rosgraph_msgs/msg/Clock"
STRING = "std_msgs/msg/String"
PARAMETER_EVENT = "rcl_interfaces/msg/ParameterEvent"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
CONTACT_STATE = "bracing_msgs/msg/ContactState"
CONTACTS = "bracing_msgs/msg/Contacts"
CONTROLLER_STATE = "bracing_msgs/msg/ControllerState"
MOTOR_COMMAND = "bracing_msgs/msg/MotorCommand"
MOTOR_STATE = "bracing_msgs/msg/MotorState"
RUN_STATUS = "bracing_msgs/msg/RunStatus"
RECORD_BATCH = "bracing_msgs/msg/RecordBatch"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"
PATH = "nav_msgs/msg/Path"
DIAGNOSTIC_STATUS = "diagnostic_msgs/msg/DiagnosticStatus"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"
ODOMETRY = "nav_msgs/msg/Odometry"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"


def bracing_msgs_dir() -> Path:
    """Directory of the bracing_msgs ``.msg`` files (installed share dir, else source)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        share = Path(get_package_share_directory("bracing_msgs")) / "msg"
        if all((share / f"{name}.msg").is_file() for name in BRACING_MSGS):
            return share
    except (ImportError, LookupError, ValueError):
        pass
    # src/bracing_core/bracing_core/typestore.py -> src/bracing_msgs/msg
    src = Path(__file__).resolve().parents[2] / "bracing_msgs" / "msg"
    if all((src / f"{name}.msg").is_file() for name in BRACING_MSGS):
        return src
    msg = "cannot find the bracing_msgs .msg files (is the workspace sourced?)"
    raise FileNotFoundError(msg)


def bracing_typestore(msg_dir: Path | None = None) -> Typestore:
    """A Jazzy typestore with the bracing_msgs types registered (from ``msg_dir`` if given).

    Without ``msg_dir`` the store is built once per process and shared (building one costs
    tens of milliseconds); treat it as read-only.
    """
    if msg_dir is None:
        return _default_typestore()
    return _build_typestore(msg_dir)


def motor_command_modes(store: Typestore | None = None) -> dict[str, int]:
    """MotorCommand's mode constants as the ``.msg`` defines them (``VOLTAGE=0``...), by the
    input_mode parameter's name for each (``voltage``...); from ``store`` if given (a bag's)."""
    constants, _ = (store or bracing_typestore()).fielddefs[MOTOR_COMMAND]
    return {name.lower(): int(value) for name, _, value in constants}


@functools.cache
def _default_typestore() -> Typestore:
    return _build_typestore(bracing_msgs_dir())


def _build_typestore(folder: Path) -> Typestore:
    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for name in BRACING_MSGS:
        text = (folder / f"{name}.msg").read_text(encoding="utf-8")
        types.update(get_types_from_msg(text, f"bracing_msgs/msg/{name}"))
    store.register(types)
    return store
