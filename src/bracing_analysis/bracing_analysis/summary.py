"""Time series and the summary table of a recorded bracing run (no rclpy needed).

``read_series(bag)`` reads a rosbag2 bag (any storage) with rosbags' AnyReader, using
only the message definitions embedded in the bag, and returns numpy time series (and the
URDF of ``robot_description``, if the bag has it, for drawing the arm). It decodes each
topic's messages column-wise (``columns``); ``columnar=False`` is the plain per-message path.
``compute_summary(series, wall_time_s)`` returns the ``summary.json`` dict (keys: README, Topics and messages):
SUMMARY_KEYS, then SUMMARY_EXTRA_KEYS (per-contact metrics ``contact_metrics``, the input mode, whether
the controller braced, the run's ``warnings``). A metric that does not apply to the run is None (null):
the brace and force errors of a run with no braced contact, the copper loss of a torque-input run
(no motor circuit), the constraint residual of a run where no contact ever held.

Times are in seconds relative to ``t0``, the first ``joint_states`` stamp (the first
stamp of any recorded message if there is no ``joint_states``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader

from bracing_analysis.columns import Layout, column, decode
from bracing_analysis.surfaces import SCENARIO_KEY, SURFACES_KEY, Shape, from_json
from bracing_analysis.truth import (
    HAND,
    TASK_AXES_KEY,
    TASK_FRAMES_KEY,
    is_ground_truth,
    task_axes_from_json,
    task_frames_from_json,
    true_positions,
)
from bracing_core import checks
from bracing_core.typestore import (
    CONTACTS,
    CONTROLLER_STATE,
    JOINT_STATE,
    MOTOR_COMMAND,
    MOTOR_STATE,
    PARAMETER_EVENT,
    PATH,
    POINT_STAMPED,
    RUN_STATUS,
    STRING,
    WRENCH_STAMPED,
    motor_command_modes,
)

FloatArray = NDArray[np.float64]
_Xyz = tuple[float, ...]

HAND_ERROR_T_MIN_S = 2.0
"""Hand errors are taken over t >= this [s] (after the initial transient)."""

SUMMARY_KEYS = (
    "hand_rms_error_m",
    "hand_max_error_m",
    "brace_rms_error_m",
    "normal_force_rms_error_n",
    "energy_consumed_j",
    "copper_loss_j",
    "constraint_residual_max_m",
    "sim_time_s",
    "wall_time_s",
    "real_time_factor",
)
SUMMARY_EXTRA_KEYS = (
    "contacts",
    "max_penetration_m",
    "input_mode",
    "bracing",
    "warnings",
    "motor_temperature_max_c",
    "motor_temperature_max_c_by_joint",
)
"""summary.json's keys after SUMMARY_KEYS (added later: tools that read SUMMARY_KEYS by position keep working)."""

CONTACT_KEYS = (
    "braced",
    "normal_force_rms_error_n",
    "brace_rms_error_m",
    "normal_force_mean_n",
    "normal_force_max_n",
    "slip_m",
    "residual_max_m",
    "active_fraction",
    "penetration_m",
)
"""The keys of each contact in summary.json's ``contacts`` (``contact_metrics``)."""


_WRENCH_TOPIC = "contact_wrench/"
_DESCRIPTION_TOPIC = "robot_description"


class BagReadError(RuntimeError):
    """The bag is missing or cannot be read."""


def _empty(cols: int = 0) -> FloatArray:
    return np.zeros((0, cols)) if cols else np.zeros(0)


@dataclass
class ContactSeries:
    """Everything recorded about one contact (bracing point)."""

    name: str
    # From `contacts` (the simulator):
    t: FloatArray = field(default_factory=_empty)  # [s]
    normal_force: FloatArray = field(default_factory=_empty)  # f_n [N]
    friction_force: FloatArray = field(default_factory=_empty)  # f_t [N]
    residual: FloatArray = field(default_factory=_empty)  # C = n . r - c [m]
    active: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    position: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    normal: FloatArray = field(default_factory=lambda: _empty(3))  # surface normal at the contact
    slip_velocity: FloatArray = field(default_factory=lambda: _empty(3))  # s = J dq, tangential [m/s]
    # From `contact_wrench/<name>` (the simulator): force on the robot, world axes:
    t_force: FloatArray = field(default_factory=_empty)  # [s]
    force: FloatArray = field(default_factory=lambda: _empty(3))  # [N]
    # From `controller_state` (the controller):
    t_ctrl: FloatArray = field(default_factory=_empty)  # [s]
    normal_force_desired: FloatArray = field(default_factory=_empty)  # f_nd [N]
    brace_desired: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    brace_actual: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    brace_measured: FloatArray = field(default_factory=lambda: _empty(3))  # [m] with sensors: the controller's view
    # contacts and controller_state samples with the same header stamp:
    t_matched: FloatArray = field(default_factory=_empty)  # [s]
    normal_force_error: FloatArray = field(default_factory=_empty)  # f_n - f_nd [N]


@dataclass(frozen=True)
class ParameterChange:
    """A node's parameters changed while it ran (recorded from /parameter_events)."""

    t: float  # [s], the run's time base
    node: str  # fully qualified (/bracing_controller)
    values: dict[str, Any]  # name -> new value (None: deleted)

    def text(self) -> str:
        """``hand.kp = [150.0, 150.0]``, one per changed parameter."""
        return ", ".join(f"{name} = {value}" for name, value in self.values.items())


@dataclass
class BagSeries:
    """Time series of one run (see the module docstring for the time base)."""

    t0_ns: int = 0
    joint_t: FloatArray = field(default_factory=_empty)  # joint_states stamps [s]
    joint_names: list[str] = field(default_factory=list)
    joint_position: FloatArray = field(default_factory=lambda: _empty(1))  # (states, joints) [rad or m]
    robot_description: str | None = None  # the URDF recorded on robot_description (newer bags)
    t: FloatArray = field(default_factory=_empty)  # controller_state stamps [s]
    hand_desired: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    hand_actual: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    # with sensors (truth.py): hand_actual is the true position, this what the controller believed
    hand_measured: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    contacts: dict[str, ContactSeries] = field(default_factory=dict)
    motor_t: FloatArray = field(default_factory=_empty)  # motor_state stamps [s]
    energy_consumed: FloatArray = field(default_factory=_empty)  # [J]
    energy_net: FloatArray = field(default_factory=_empty)  # [J]
    copper_loss: FloatArray = field(default_factory=_empty)  # [J]
    motor_names: list[str] = field(default_factory=list)  # motor_state's joint names
    # (motor_state messages, motors) winding temperatures [degC]; NaN rows where a message has none (torque
    # input, the thermal model off, a bag from before it), so no columns at all when none has any
    motor_temperature: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    topic_counts: dict[str, int] = field(default_factory=dict)  # messages per topic
    input_mode: str | None = None  # motor_command's mode ("voltage", "torque"); None if none was recorded
    scenario: str | None = None  # the scenario's name (bag metadata, the recorder's --scenario); None: unknown
    surfaces: dict[str, Shape] = field(default_factory=dict)  # each contact's surface (bag metadata)
    parameter_changes: list[ParameterChange] = field(default_factory=list)  # the controller's, in time order
    # The world axes ("x", "y", "z") of the controller's tasks (bag metadata): the hand's (None: not said) and
    # each braced contact's (a contact not listed: not said). The report draws each (drawing.hand_axes).
    hand_axes: list[str] | None = None
    brace_task_axes: dict[str, list[str]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)  # what the nodes warned about (run_status), in time order
    targets: list[TargetSent] = field(default_factory=list)  # sent while it ran, in time order


def _stamp_ns(msg: Any) -> int:
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _xyz(point: Any) -> tuple[float, float, float]:
    return (float(point.x), float(point.y), float(point.z))


def resolve_bag(path: Path) -> Path:
    """The bag directory: `path` itself, or `path/bag` when given the run directory."""
    if not path.exists():
        msg = f"bag not found: {path}"
        raise BagReadError(msg)
    if path.is_dir() and not (path / "metadata.yaml").exists() and (path / "bag").is_dir():
        return path / "bag"
    return path


def read_series(bag: str | Path, columnar: bool = True) -> BagSeries:
    """Read a recorded run into time series. Raises BagReadError if unreadable.

    ``columnar=False`` decodes every message with rosbags' deserializer (the reference the
    columnar decoding is tested against; same result).
    """
    path = resolve_bag(Path(bag))
    # Columnar: read_series of a 10 s bag (50k messages) 1.5 s -> 0.25 s, best of 3 (rosbags' reading: 0.2 s of it).
    series = _read_columnar(path) if columnar else _read_general(path)
    _read_ground_truth(series, path)
    return series


def _read_ground_truth(series: BagSeries, path: Path) -> None:
    """With sensors (truth.py): the task positions from ground_truth/joint_states, the controller's beside them."""
    if not any(is_ground_truth(topic) and topic.endswith("/joint_states") for topic in series.topic_counts):
        return
    frames = task_frames_from_json(_custom_data(path).get(TASK_FRAMES_KEY, ""))
    if not frames or not series.robot_description:
        return  # a bag without the task frames: the controller's view is all there is
    stamps: list[int] = []
    rows: list[list[float]] = []
    names: list[str] = []
    try:
        with AnyReader([path]) as reader:
            wanted = [c for c in reader.connections if is_ground_truth(c.topic) and c.msgtype == JOINT_STATE]
            for conn, _, raw in reader.messages(connections=wanted):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                names = names or list(msg.name)
                stamps.append(_stamp_ns(msg))
                rows.append(_by_name(msg, names))
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        raise BagReadError(f"cannot read bag {path}: {exc}") from exc
    task = [frames[HAND], *frames["braces"].values()]
    truth = true_positions(series.robot_description, np.array(stamps, dtype=np.int64), names, np.array(rows), task)
    apply_ground_truth(series, truth, frames)


def apply_ground_truth(series: BagSeries, truth: Mapping[int, np.ndarray], frames: Mapping[str, Any]) -> None:
    """The series' task positions from ``truth`` ({stamp: (1 + braces, 3)}, hand first then ``frames``'
    braces in order), the controller's own beside them; a controller state without a true state keeps its own."""
    braces = list(frames.get("braces", {}))
    stamps = np.round(series.t * 1e9).astype(np.int64) + series.t0_ns
    series.hand_measured = series.hand_actual.copy()
    series.hand_actual = _replaced(series.hand_actual, stamps, truth, 0)
    for j, name in enumerate(braces):
        cs = series.contacts.get(name)
        if cs is None or not cs.t_ctrl.size:
            continue
        ctrl_stamps = np.round(cs.t_ctrl * 1e9).astype(np.int64) + series.t0_ns
        cs.brace_measured = cs.brace_actual.copy()
        cs.brace_actual = _replaced(cs.brace_actual, ctrl_stamps, truth, j + 1)


def _replaced(values: np.ndarray, stamps: np.ndarray, truth: Mapping[int, np.ndarray], row: int) -> np.ndarray:
    out = values.copy()
    for k, stamp in enumerate(stamps.tolist()):
        true = truth.get(int(stamp))
        if true is not None:
            out[k] = true[row]
    return out


def _wanted(reader: AnyReader, counts: dict[str, int]) -> list[Any]:
    """The connections read_series decodes (and every topic's message count into ``counts``)."""
    for conn in reader.connections:
        counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount
    return [
        c
        for c in reader.connections
        if not is_ground_truth(c.topic)  # _read_ground_truth's, after the rest
        and (
            c.msgtype in (JOINT_STATE, CONTACTS, CONTROLLER_STATE, MOTOR_STATE)
            or (c.msgtype == WRENCH_STAMPED and _WRENCH_TOPIC in c.topic)
            or (c.msgtype == STRING and c.topic.endswith(_DESCRIPTION_TOPIC))
        )
    ]


def _input_mode(reader: AnyReader) -> str | None:
    """The mode of the first motor_command (the controller sends one mode for a whole run), decoded
    by rosbags: both read paths call this, so they agree by construction; None if none was recorded
    or the mode is not one MotorCommand defines."""
    commands = [c for c in reader.connections if c.msgtype == MOTOR_COMMAND]
    if not commands:  # (an empty list would make reader.messages read every topic)
        return None
    for conn, _, raw in reader.messages(connections=commands):
        command: Any = reader.deserialize(raw, conn.msgtype)
        names = {code: name for name, code in motor_command_modes(reader.typestore).items()}  # the bag's .msg
        return names.get(int(command.mode))
    return None


def _custom_data(path: Path) -> dict[str, str]:
    """The bag's metadata ``custom_data`` (what the recorder noted: scenario, surfaces, tasks); {} if none."""
    try:
        document = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
        data = document["rosbag2_bagfile_information"].get("custom_data") or {}
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def _describe(series: BagSeries, path: Path) -> None:
    """The run's scenario, surfaces and task axes from the bag's metadata, into ``series``."""
    data = _custom_data(path)
    series.scenario = data.get(SCENARIO_KEY) or None
    series.surfaces = from_json(data.get(SURFACES_KEY, "{}"))
    series.hand_axes, series.brace_task_axes = task_axes_from_json(data.get(TASK_AXES_KEY, "{}"))


_VALUE_FIELDS = {
    1: "bool_value",
    2: "integer_value",
    3: "double_value",
    4: "string_value",
    5: "byte_array_value",
    6: "bool_array_value",
    7: "integer_array_value",
    8: "double_array_value",
    9: "string_array_value",
}
"""rcl_interfaces/ParameterType -> the ParameterValue field that holds it."""


@dataclass(frozen=True)
class TargetSent:
    """A target sent to the controller while it ran (hand_target, hand_path, brace_target/<contact>)."""

    t: float  # [s], the run's time base: when the recorder got it (the sim time of the last /clock)
    task: str  # "hand" or the contact's name
    points: FloatArray  # (poses, 3) [m], world (one row for a point)
    times: FloatArray  # (poses,) [s], the run's time base: a path's pose stamps; a point's = t


_Target = tuple[int, str, list[tuple[float, float, float]], list[int]]


def _targets(reader: AnyReader) -> list[_Target]:
    """(bag time [ns], task, points, pose stamps [ns]) of each recorded target, in time order."""
    connections = [
        c
        for c in reader.connections
        if (c.msgtype == POINT_STAMPED and c.topic.rsplit("/", 1)[-1] == "hand_target")
        or (c.msgtype == POINT_STAMPED and "brace_target/" in c.topic)
        or (c.msgtype == PATH and c.topic.endswith("hand_path"))
    ]
    if not connections:  # (an empty list would make reader.messages read every topic)
        return []
    out: list[_Target] = []
    for conn, stamp, raw in reader.messages(connections=connections):
        msg: Any = reader.deserialize(raw, conn.msgtype)
        task = conn.topic.split("brace_target/", 1)[1] if "brace_target/" in conn.topic else "hand"
        if conn.msgtype == PATH:
            points = [_xyz(pose.pose.position) for pose in msg.poses]
            times = [_stamp_ns(pose) for pose in msg.poses]
        else:
            points, times = [_xyz(msg.point)], [stamp]
        out.append((stamp, task, points, times))
    return sorted(out, key=lambda e: e[0])


def _sent(targets: list[_Target], t0: int) -> list[TargetSent]:
    return [
        TargetSent(
            (stamp - t0) * 1e-9,
            task,
            np.array(points, dtype=float).reshape(-1, 3),
            ((np.array(times, dtype=np.int64) - t0) * 1e-9).astype(np.float64),
        )
        for stamp, task, points, times in targets
    ]


def _parameter_value(value: Any) -> Any:
    held = getattr(value, _VALUE_FIELDS.get(int(value.type), ""), None)
    return held.tolist() if isinstance(held, np.ndarray) else list(held) if isinstance(held, list) else held


def _parameter_events(reader: AnyReader) -> list[tuple[int, str, dict[str, Any]]]:
    """(stamp [ns], node, {name: new value}) of each recorded /parameter_events message that changes
    or deletes a value, decoded by rosbags (a few per run); both read paths call this."""
    connections = [c for c in reader.connections if c.msgtype == PARAMETER_EVENT]
    if not connections:  # (an empty list would make reader.messages read every topic)
        return []
    out = []
    for conn, _, raw in reader.messages(connections=connections):
        event: Any = reader.deserialize(raw, conn.msgtype)
        values = {str(p.name): _parameter_value(p.value) for p in event.changed_parameters}
        values.update({str(p.name): None for p in event.deleted_parameters})
        if values:
            stamp = int(event.stamp.sec) * 1_000_000_000 + int(event.stamp.nanosec)
            out.append((stamp, str(event.node), values))
    return sorted(out, key=lambda e: e[0])


def _recorded_warnings(reader: AnyReader) -> list[str]:
    """The warnings the nodes said on run_status (the recorder keeps only those), in time order, decoded
    by rosbags (a few per run); both read paths call this."""
    connections = [c for c in reader.connections if c.msgtype == RUN_STATUS]
    if not connections:  # (an empty list would make reader.messages read every topic)
        return []
    out = []
    for conn, stamp, raw in reader.messages(connections=connections):
        status: Any = reader.deserialize(raw, conn.msgtype)
        if status.text:
            out.append((stamp, str(status.text)))
    return [text for _, text in sorted(out, key=lambda w: w[0])]


def _changes(events: list[tuple[int, str, dict[str, Any]]], t0: int) -> list[ParameterChange]:
    return [ParameterChange((stamp - t0) * 1e-9, node, values) for stamp, node, values in events]


def _read_general(path: Path) -> BagSeries:
    joint: list[tuple[int, Any]] = []
    wrenches: dict[str, list[tuple[int, tuple[float, float, float]]]] = {}
    description: str | None = None
    ctrl: list[tuple[int, Any]] = []
    contacts: list[tuple[int, Any]] = []
    motor: list[tuple[int, float, float, float]] = []
    motor_msgs: list[tuple[int, Any]] = []
    counts: dict[str, int] = {}
    try:
        with AnyReader([path]) as reader:
            wanted = _wanted(reader, counts)
            mode = _input_mode(reader)
            events = _parameter_events(reader)
            warnings = _recorded_warnings(reader)
            targets = _targets(reader)
            for conn, _, raw in reader.messages(connections=wanted):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                if conn.msgtype == STRING:
                    description = description or str(msg.data)
                    continue
                stamp = _stamp_ns(msg)
                if conn.msgtype == JOINT_STATE:
                    joint.append((stamp, msg))
                elif conn.msgtype == WRENCH_STAMPED:
                    name = conn.topic.rsplit(_WRENCH_TOPIC, 1)[1]
                    wrenches.setdefault(name, []).append((stamp, _xyz(msg.wrench.force)))
                elif conn.msgtype == CONTROLLER_STATE:
                    ctrl.append((stamp, msg))
                elif conn.msgtype == CONTACTS:
                    contacts.append((stamp, msg))
                else:
                    motor.append((stamp, float(msg.energy_consumed), float(msg.energy_net), float(msg.copper_loss)))
                    motor_msgs.append((stamp, msg))
    except BagReadError:
        raise
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        msg = f"cannot read bag {path}: {exc}"
        raise BagReadError(msg) from exc

    joint.sort(key=lambda x: x[0])
    ctrl.sort(key=lambda x: x[0])
    contacts.sort(key=lambda x: x[0])
    motor.sort(key=lambda x: x[0])
    motor_msgs.sort(key=lambda x: x[0])
    if joint:
        t0 = joint[0][0]
    else:
        firsts = [lst[0][0] for lst in (ctrl, contacts, motor) if lst]
        t0 = min(firsts) if firsts else 0

    def sec(ns: int) -> float:
        return (ns - t0) * 1e-9

    series = BagSeries(t0_ns=t0, topic_counts=counts, robot_description=description, input_mode=mode)
    series.parameter_changes = _changes(events, t0)
    series.warnings = warnings
    series.targets = _sent(targets, t0)
    _describe(series, path)
    series.joint_t = np.array([sec(s) for s, _ in joint], dtype=float)
    if joint:
        series.joint_names = [str(n) for n in joint[0][1].name]
        series.joint_position = np.array([_by_name(m, series.joint_names) for _, m in joint], dtype=float)
    series.t = np.array([sec(s) for s, _ in ctrl], dtype=float)
    series.hand_desired = np.array([_xyz(m.hand_desired) for _, m in ctrl], dtype=float)
    series.hand_actual = np.array([_xyz(m.hand_actual) for _, m in ctrl], dtype=float)
    series.hand_desired = series.hand_desired.reshape(-1, 3)
    series.hand_actual = series.hand_actual.reshape(-1, 3)
    if motor:
        arr = np.array(motor, dtype=float)
        series.motor_t = np.array([sec(s) for s, *_ in motor], dtype=float)
        series.energy_consumed = arr[:, 1]
        series.energy_net = arr[:, 2]
        series.copper_loss = arr[:, 3]
        series.motor_names = [str(n) for n in motor_msgs[0][1].name]
        width = len(series.motor_names)
        temperatures = [list(getattr(m, "temperature", ())) for _, m in motor_msgs]
        if any(len(row) == width > 0 for row in temperatures):
            series.motor_temperature = np.array(
                [row if len(row) == width else [math.nan] * width for row in temperatures], dtype=float
            )

    # Per contact, from the simulator.
    sim_rows: dict[str, list[tuple[int, float, float, float, bool, _Xyz, _Xyz, _Xyz]]] = {}
    for stamp, msg in contacts:
        for c in msg.contacts:
            sim_rows.setdefault(str(c.name), []).append(
                (
                    stamp,
                    float(c.normal_force),
                    float(c.friction_force),
                    float(c.residual),
                    bool(c.active),
                    _xyz(c.position),
                    _xyz(c.normal),
                    _xyz(c.slip_velocity),
                )
            )
    # Per contact, from the controller.
    ctrl_rows: dict[str, list[tuple[int, float, tuple[float, ...], tuple[float, ...]]]] = {}
    for stamp, msg in ctrl:
        names = list(msg.contact_name)
        for j, name in enumerate(names):
            fnd = float(msg.desired_normal_force[j]) if j < len(msg.desired_normal_force) else math.nan
            bd = _xyz(msg.brace_desired[j]) if j < len(msg.brace_desired) else (math.nan,) * 3
            ba = _xyz(msg.brace_actual[j]) if j < len(msg.brace_actual) else (math.nan,) * 3
            ctrl_rows.setdefault(str(name), []).append((stamp, fnd, bd, ba))

    for name in list(sim_rows) + [n for n in ctrl_rows if n not in sim_rows]:
        cs = ContactSeries(name=name)
        rows = sim_rows.get(name, [])
        if rows:
            cs.t = np.array([sec(r[0]) for r in rows], dtype=float)
            cs.normal_force = np.array([r[1] for r in rows], dtype=float)
            cs.friction_force = np.array([r[2] for r in rows], dtype=float)
            cs.residual = np.array([r[3] for r in rows], dtype=float)
            cs.active = np.array([r[4] for r in rows], dtype=bool)
            cs.position = np.array([r[5] for r in rows], dtype=float).reshape(-1, 3)
            cs.normal = np.array([r[6] for r in rows], dtype=float).reshape(-1, 3)
            cs.slip_velocity = np.array([r[7] for r in rows], dtype=float).reshape(-1, 3)
        forces = sorted(wrenches.get(name, []))
        if forces:
            cs.t_force = np.array([sec(s) for s, _ in forces], dtype=float)
            cs.force = np.array([f for _, f in forces], dtype=float).reshape(-1, 3)
        crow = ctrl_rows.get(name, [])
        if crow:
            cs.t_ctrl = np.array([sec(r[0]) for r in crow], dtype=float)
            cs.normal_force_desired = np.array([r[1] for r in crow], dtype=float)
            cs.brace_desired = np.array([r[2] for r in crow], dtype=float).reshape(-1, 3)
            cs.brace_actual = np.array([r[3] for r in crow], dtype=float).reshape(-1, 3)
        # Match f_n (simulator) and f_nd (controller) by header stamp.
        desired = {r[0]: r[1] for r in crow}
        matched = [(r[0], r[1] - desired[r[0]]) for r in rows if r[0] in desired]
        cs.t_matched = np.array([sec(s) for s, _ in matched], dtype=float)
        cs.normal_force_error = np.array([e for _, e in matched], dtype=float)
        series.contacts[name] = cs
    return series


def _kind(conn: Any) -> tuple[str, str]:
    """What the columnar path groups messages by: the type, and the contact of a wrench topic."""
    return (conn.msgtype, conn.topic.rsplit(_WRENCH_TOPIC, 1)[1] if conn.msgtype == WRENCH_STAMPED else "")


@dataclass
class _Messages:
    """The messages of one kind in bag order, decoded column-wise, and their stamp order."""

    layouts: list[Layout]
    count: int
    stamp: NDArray[np.int64]  # header stamps [ns]
    order: NDArray[np.intp]  # bag order -> stamp order (stable, like list.sort)
    rank: NDArray[np.intp]  # each message's place in stamp order

    def by_stamp(self, path: str) -> NDArray[Any]:
        return column(self.layouts, path, self.count)[self.order]

    def xyz(self, path: str) -> FloatArray:
        return np.stack([self.by_stamp(f"{path}.{axis}") for axis in "xyz"], axis=1).astype(float)


def _messages(typestore: Any, msgtype: str, raws: list[bytes]) -> _Messages:
    layouts = decode(typestore, msgtype, raws)
    count = len(raws)
    sec = column(layouts, "header.stamp.sec", count).astype(np.int64)
    stamp = sec * 1_000_000_000 + column(layouts, "header.stamp.nanosec", count).astype(np.int64)
    order = np.argsort(stamp, kind="stable")
    rank = np.empty(count, dtype=np.intp)
    rank[order] = np.arange(count)
    return _Messages(layouts, count, stamp, order, rank)


@dataclass
class _Rows:
    """One contact's entries in the messages of one kind: in stamp order, then order in the message."""

    entries: list[tuple[Layout, int]]  # layout, position of the contact in its messages
    perm: NDArray[np.intp]  # concatenated entries -> row order
    stamp: NDArray[np.int64]  # of each row [ns]
    first: tuple[int, int]  # (rank, position) of the first row

    def take(self, path: str) -> NDArray[Any]:
        """The value at ``path`` (``{j}``: the contact's position) of each row, NaN where a message lacks it."""
        parts = []
        for layout, j in self.entries:
            values = layout.values.get(path.format(j=j))
            parts.append(np.full(len(layout.index), math.nan) if values is None else values)
        return np.concatenate(parts)[self.perm]

    def xyz(self, path: str) -> FloatArray:
        return np.stack([self.take(f"{path}.{axis}") for axis in "xyz"], axis=1).astype(float)


def _per_contact(messages: _Messages, sequence: str, name: str) -> dict[str, _Rows]:
    """Contact name -> its rows; ``name`` is the path of a contact's name (``{j}``: its position)."""
    entries: dict[str, list[tuple[Layout, int]]] = {}
    for layout in messages.layouts:
        for j in range(layout.lengths[sequence]):
            entries.setdefault(layout.strings[name.format(j=j)], []).append((layout, j))
    rows = {}
    for contact, found in entries.items():
        index = np.concatenate([layout.index for layout, _ in found])
        slot = np.concatenate([np.full(len(layout.index), j) for layout, j in found])
        perm = np.lexsort((slot, messages.rank[index]))
        first = (int(messages.rank[index[perm[0]]]), int(slot[perm[0]]))
        rows[contact] = _Rows(found, perm, messages.stamp[index][perm], first)
    # Like the general path's dicts: contacts in the order they first appear.
    return dict(sorted(rows.items(), key=lambda item: item[1].first))


def _joint_positions(joint: _Messages, names: list[str]) -> FloatArray:
    """_by_name per layout: every JointState's positions in the order of ``names``."""
    blocks: list[tuple[Layout, list[str | None]]] = []
    for layout in joint.layouts:
        count, own = layout.lengths["position"], layout.texts("name")
        if own == names:
            paths: list[str | None] = [f"position[{j}]" for j in range(count)]
        else:  # as _by_name's dict: zip stops at the shorter list, a repeated name's last position wins
            where = dict(zip(own, range(count), strict=False))
            paths = [f"position[{where[n]}]" if n in where else None for n in names]
        blocks.append((layout, paths))
    widths = {len(paths) for _, paths in blocks}
    if len(widths) > 1:  # what np.array raises on the general path's ragged rows
        msg = "JointState messages with different numbers of positions"
        raise ValueError(msg)
    out = np.empty((joint.count, widths.pop()))
    for layout, paths in blocks:
        for k, path in enumerate(paths):
            out[layout.index, k] = math.nan if path is None else layout.values[path]
    return out[joint.order]


def _motor_temperatures(motor: _Messages) -> tuple[list[str], FloatArray]:
    """The general path's motor names and temperatures, column-wise: the first message's names (in stamp
    order), each message's temperatures where it has one per name, NaN where not."""
    first = next(layout for layout in motor.layouts if np.any(layout.index == motor.order[0]))
    names = first.texts("name")
    width = len(names)
    out = np.full((motor.count, width), math.nan)
    filled = False
    for layout in motor.layouts:
        if width and layout.lengths.get("temperature", 0) == width:
            filled = True
            for k in range(width):
                out[layout.index, k] = layout.values[f"temperature[{k}]"]
    return names, out[motor.order] if filled else np.zeros((0, 0))


def _match(rows: _Rows, crow: _Rows) -> tuple[NDArray[np.int64], FloatArray]:
    """Stamps and f_n - f_nd of the contacts rows whose stamp a controller_state row has (its last such row)."""
    stamps, desired = crow.stamp, crow.take("desired_normal_force[{j}]").astype(float)
    last = len(stamps) - 1 - np.unique(stamps[::-1], return_index=True)[1]  # sorted by stamp
    at = np.minimum(np.searchsorted(stamps[last], rows.stamp), len(last) - 1)
    hit = stamps[last][at] == rows.stamp
    return rows.stamp[hit], rows.take("contacts[{j}].normal_force").astype(float)[hit] - desired[last][at[hit]]


def _read_columnar(path: Path) -> BagSeries:
    """read_series decoding each kind of message column-wise (columns.decode)."""
    counts: dict[str, int] = {}
    raws: dict[tuple[str, str], list[bytes]] = {(t, ""): [] for t in (JOINT_STATE, CONTROLLER_STATE, CONTACTS)}
    raws[(MOTOR_STATE, "")] = []
    try:
        with AnyReader([path]) as reader:
            wanted = _wanted(reader, counts)
            mode = _input_mode(reader)
            events = _parameter_events(reader)
            warnings = _recorded_warnings(reader)
            targets = _targets(reader)
            for conn, _, raw in reader.messages(connections=wanted):
                raws.setdefault(_kind(conn), []).append(raw)
            store = reader.typestore
            texts = decode(store, STRING, raws.pop((STRING, ""), []))
            messages = {kind: _messages(store, kind[0], lst) for kind, lst in raws.items()}
    except BagReadError:
        raise
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        msg = f"cannot read bag {path}: {exc}"
        raise BagReadError(msg) from exc

    joint, ctrl = messages[(JOINT_STATE, "")], messages[(CONTROLLER_STATE, "")]
    sim, motor = messages[(CONTACTS, "")], messages[(MOTOR_STATE, "")]
    if joint.count:
        t0 = int(joint.stamp[joint.order[0]])
    else:
        firsts = [int(m.stamp.min()) for m in (ctrl, sim, motor) if m.count]
        t0 = min(firsts) if firsts else 0

    def sec(ns: NDArray[np.int64]) -> FloatArray:
        return ((ns - t0) * 1e-9).astype(float, copy=False)

    # The first non-empty robot_description in bag order ("" if all are empty).
    filled = sorted((int(layout.index[0]), layout.strings["data"]) for layout in texts if layout.strings["data"])
    description = filled[0][1] if filled else "" if texts else None
    series = BagSeries(t0_ns=t0, topic_counts=counts, robot_description=description, input_mode=mode)
    series.parameter_changes = _changes(events, t0)
    series.warnings = warnings
    series.targets = _sent(targets, t0)
    _describe(series, path)
    series.joint_t = sec(joint.stamp[joint.order])
    if joint.count:
        first = next(layout for layout in joint.layouts if np.any(layout.index == joint.order[0]))
        series.joint_names = first.texts("name")
        series.joint_position = _joint_positions(joint, series.joint_names)
    series.t = sec(ctrl.stamp[ctrl.order])
    series.hand_desired = ctrl.xyz("hand_desired")
    series.hand_actual = ctrl.xyz("hand_actual")
    if motor.count:
        series.motor_t = sec(motor.stamp[motor.order])
        series.energy_consumed = motor.by_stamp("energy_consumed").astype(float)
        series.energy_net = motor.by_stamp("energy_net").astype(float)
        series.copper_loss = motor.by_stamp("copper_loss").astype(float)
        series.motor_names, series.motor_temperature = _motor_temperatures(motor)

    sim_rows = _per_contact(sim, "contacts", "contacts[{j}].name")
    ctrl_rows = _per_contact(ctrl, "contact_name", "contact_name[{j}]")
    for name in list(sim_rows) + [n for n in ctrl_rows if n not in sim_rows]:
        cs = ContactSeries(name=name)
        rows = sim_rows.get(name)
        if rows is not None:
            cs.t = sec(rows.stamp)
            cs.normal_force = rows.take("contacts[{j}].normal_force").astype(float)
            cs.friction_force = rows.take("contacts[{j}].friction_force").astype(float)
            cs.residual = rows.take("contacts[{j}].residual").astype(float)
            cs.active = rows.take("contacts[{j}].active").astype(bool)
            cs.position = rows.xyz("contacts[{j}].position")
            cs.normal = rows.xyz("contacts[{j}].normal")
            cs.slip_velocity = rows.xyz("contacts[{j}].slip_velocity")
        wrench = messages.get((WRENCH_STAMPED, name))
        if wrench is not None and wrench.count:
            force = [column(wrench.layouts, f"wrench.force.{axis}", wrench.count).astype(float) for axis in "xyz"]
            by_force = np.lexsort((*force[::-1], wrench.stamp))  # as sorted() of (stamp, force) tuples
            cs.t_force = sec(wrench.stamp[by_force])
            cs.force = np.stack(force, axis=1)[by_force]
        crow = ctrl_rows.get(name)
        if crow is not None:
            cs.t_ctrl = sec(crow.stamp)
            cs.normal_force_desired = crow.take("desired_normal_force[{j}]").astype(float)
            cs.brace_desired = crow.xyz("brace_desired[{j}]")
            cs.brace_actual = crow.xyz("brace_actual[{j}]")
            if rows is not None:
                stamps, cs.normal_force_error = _match(rows, crow)
                cs.t_matched = sec(stamps)
        series.contacts[name] = cs
    return series


def _by_name(msg: Any, names: list[str]) -> list[float]:
    """A JointState's positions in the order of ``names`` (NaN for a joint it lacks)."""
    if list(msg.name) == names:
        return [float(v) for v in msg.position]
    value = dict(zip(msg.name, msg.position, strict=False))
    return [float(value.get(n, math.nan)) for n in names]


def _rms(values: FloatArray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def _braced(cs: ContactSeries) -> bool:
    """The controller keeps a desired force on the contact (it names it in controller_state)."""
    return bool(cs.t_ctrl.size)


def _active(cs: ContactSeries) -> NDArray[np.bool_]:
    """Which of the contact's samples are active; all of them for a series made without the flags
    (by hand, in tests and tools), as the summary counted every sample before it knew of them."""
    return cs.active if cs.active.shape == cs.t.shape else np.ones(cs.t.shape, dtype=bool)


def _brace_errors(cs: ContactSeries) -> FloatArray:
    """|r_dj - r_j| [m] at each controller_state sample that has both (none for an unbraced contact)."""
    error = np.linalg.norm(cs.brace_desired - cs.brace_actual, axis=1)
    return error[np.isfinite(error)]


def _force_errors(cs: ContactSeries) -> FloatArray:
    """f_n - f_nd [N] where both are known (none for an unbraced contact)."""
    return cs.normal_force_error[np.isfinite(cs.normal_force_error)]


def _slip(cs: ContactSeries, active: NDArray[np.bool_]) -> float | None:
    """How far the contact point slid while active [m]: the trapezoid rule on the contacts stamps
    of |s| (0 where inactive, so touchdown and lift-off intervals count half). None if the series
    has no slip velocities (a series not read from a bag)."""
    if cs.slip_velocity.shape != (cs.t.size, 3):
        return None
    speed = np.where(active, np.linalg.norm(cs.slip_velocity, axis=1), 0.0)
    # By hand: np.trapezoid is numpy >= 2 only (a Jazzy workspace's system numpy is 1.26).
    return float(np.sum(np.diff(cs.t) * (speed[1:] + speed[:-1]) / 2))


def _rms_or_none(values: FloatArray) -> float | None:
    return _rms(values) if values.size else None


def contact_metrics(cs: ContactSeries) -> dict[str, Any]:
    """One contact's entry of summary.json's ``contacts`` (keys: CONTACT_KEYS); None where a metric
    does not apply: the errors of a contact the controller does not brace, the force and residual
    of a contact never active."""
    braced, active = _braced(cs), _active(cs)
    force, residual = cs.normal_force[active], cs.residual[active]
    return {
        "braced": braced,
        "normal_force_rms_error_n": _rms_or_none(_force_errors(cs)) if braced else None,
        "brace_rms_error_m": _rms_or_none(_brace_errors(cs)) if braced else None,
        "normal_force_mean_n": float(np.mean(force)) if force.size else None,
        "normal_force_max_n": float(np.max(force)) if force.size else None,
        "slip_m": _slip(cs, active),
        "residual_max_m": float(np.max(np.abs(residual))) if residual.size else None,
        "active_fraction": float(np.mean(active)) if active.size else None,
        # Over every sample: an obstacle's frame below its surface has penetrated, active or not.
        "penetration_m": max(0.0, -float(np.min(cs.residual))) if cs.residual.size else None,
    }


def compute_summary(
    series: BagSeries, wall_time_s: float | None = None, warnings: Sequence[str] = ()
) -> dict[str, Any]:
    """The summary.json dict (keys: SUMMARY_KEYS, then SUMMARY_EXTRA_KEYS, in that order).

    A value that the recorded data cannot give (e.g. no controller_state after 2 s, no
    motor_state) or that does not apply is None. The brace and force errors count the braced
    contacts only (None for a run without any), the constraint residual every contact while
    active (None if none ever is); a torque-input run has no copper loss (None).
    ``contacts`` has every contact of the ``contacts`` topic (``contact_metrics``). ``warnings``:
    the given ones (what the data cannot show: a target out of reach), then ``data_warnings``, then
    what the nodes warned about during the run (``series.warnings``: the bag's run_status), each once.
    """
    out: dict[str, Any] = dict.fromkeys(SUMMARY_KEYS + SUMMARY_EXTRA_KEYS)

    mask = series.t >= HAND_ERROR_T_MIN_S - 1e-9
    if np.any(mask):
        err = np.linalg.norm(series.hand_desired[mask] - series.hand_actual[mask], axis=1)
        out["hand_rms_error_m"] = _rms(err)
        out["hand_max_error_m"] = float(np.max(err))

    contacts = list(series.contacts.values())
    braced = [c for c in contacts if _braced(c)]
    # Over every sample of every braced contact (an unbraced one has no target); None without any.
    for key, errors in (("brace_rms_error_m", _brace_errors), ("normal_force_rms_error_n", _force_errors)):
        out[key] = _rms_or_none(np.concatenate([np.zeros(0), *(errors(c) for c in braced)]))
    residual = np.concatenate([np.zeros(0), *(c.residual[_active(c)] for c in contacts)])
    out["constraint_residual_max_m"] = float(np.max(np.abs(residual))) if residual.size else None

    if series.motor_t.size:
        out["energy_consumed_j"] = float(series.energy_consumed[-1])
        # Torque input drives the joints directly: no motor circuit, so no copper loss to speak of.
        out["copper_loss_j"] = None if series.input_mode == "torque" else float(series.copper_loss[-1])
    # The hottest each winding got, and the hottest of all; None where no temperature was recorded.
    temperature = series.motor_temperature
    if temperature.shape[1] and np.isfinite(temperature).any():
        hottest = np.max(np.where(np.isfinite(temperature), temperature, -np.inf), axis=0)
        out["motor_temperature_max_c_by_joint"] = {
            name: float(value) if np.isfinite(value) else None
            for name, value in zip(series.motor_names, hottest, strict=True)
        }
        out["motor_temperature_max_c"] = float(np.max(hottest))

    if series.joint_t.size:
        out["sim_time_s"] = float(series.joint_t[-1] - series.joint_t[0])
    if wall_time_s is not None:
        out["wall_time_s"] = float(wall_time_s)
        if out["sim_time_s"] is not None and wall_time_s > 0:
            out["real_time_factor"] = out["sim_time_s"] / float(wall_time_s)

    out["contacts"] = {c.name: contact_metrics(c) for c in contacts if c.t.size}
    penetrations = [m["penetration_m"] for m in out["contacts"].values() if m["penetration_m"] is not None]
    out["max_penetration_m"] = max(penetrations) if penetrations else None
    out["input_mode"] = series.input_mode
    out["bracing"] = bool(braced) if series.t.size else None
    out["warnings"] = list(dict.fromkeys([*warnings, *data_warnings(series), *series.warnings]))
    return out


def data_warnings(series: BagSeries) -> list[str]:
    """What the controller's recorded data shows to be amiss, once per contact (the texts of
    ``bracing_core.checks``, as the controller logs them): a braced contact's desired force <= 0, from
    the start or once retuned so. (What the simulator warns about it says itself: ``series.warnings``.)"""
    out = []
    for cs in series.contacts.values():
        if not _braced(cs):
            continue  # an obstacle is pushed or left as the arm goes
        desired = cs.normal_force_desired
        low = np.flatnonzero(np.isfinite(desired) & (desired <= 0.0))
        if low.size:
            k = int(low[0])
            out.append(str(checks.desired_force_warning(cs.name, float(desired[k]), float(cs.t_ctrl[k]))))
    return out


def flat_summary(summary: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """The summary with its nested dicts (per contact) as dotted keys: ``contacts.elbow.slip_m``."""
    out: dict[str, Any] = {}
    for key, value in summary.items():
        if isinstance(value, dict) and value:
            out.update(flat_summary(value, f"{prefix}{key}."))
        else:
            out[prefix + key] = value
    return out


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as an aligned two-column table, a line per value (per contact metric too), then
    a line per warning."""
    flat = flat_summary(summary)
    warnings = flat.pop("warnings", None) or []
    width = max((len(k) for k in flat), default=0)
    lines = []
    for key, value in flat.items():
        text = "n/a" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<{width}}  {text}")
    lines += [f"warning: {warning}" for warning in warnings]
    return "\n".join(lines)


def scenario_name(series: BagSeries) -> str:
    """The run's scenario: as the bag notes it, else its robot's name (URDF), else unknown."""
    if series.scenario:
        return series.scenario
    robot = re.search(r"<robot\b[^>]*\bname\s*=\s*[\"']([^\"']+)", series.robot_description or "")
    return f"robot {robot.group(1)}" if robot else "unknown scenario"
