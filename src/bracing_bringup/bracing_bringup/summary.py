"""Time series and the summary table of a recorded bracing run (no rclpy needed).

``read_series(bag)`` reads a rosbag2 bag (any storage) with rosbags' AnyReader, using
only the message definitions embedded in the bag, and returns numpy time series (and the
URDF of ``robot_description``, if the bag has it, for drawing the arm).
``compute_summary(series, wall_time_s)`` returns the ``summary.json`` dict (keys: README, Topics and messages).

Times are in seconds relative to ``t0``, the first ``joint_states`` stamp (the first
stamp of any recorded message if there is no ``joint_states``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader

FloatArray = NDArray[np.float64]

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

_JOINT_STATE = "sensor_msgs/msg/JointState"
_CONTACTS = "bracing_msgs/msg/Contacts"
_CONTROLLER_STATE = "bracing_msgs/msg/ControllerState"
_MOTOR_STATE = "bracing_msgs/msg/MotorState"
_WRENCH = "geometry_msgs/msg/WrenchStamped"
_STRING = "std_msgs/msg/String"
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
    # From `contact_wrench/<name>` (the simulator): force on the robot, world axes:
    t_force: FloatArray = field(default_factory=_empty)  # [s]
    force: FloatArray = field(default_factory=lambda: _empty(3))  # [N]
    # From `controller_state` (the controller):
    t_ctrl: FloatArray = field(default_factory=_empty)  # [s]
    normal_force_desired: FloatArray = field(default_factory=_empty)  # f_nd [N]
    brace_desired: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    brace_actual: FloatArray = field(default_factory=lambda: _empty(3))  # [m]
    # contacts and controller_state samples with the same header stamp:
    t_matched: FloatArray = field(default_factory=_empty)  # [s]
    normal_force_error: FloatArray = field(default_factory=_empty)  # f_n - f_nd [N]


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
    contacts: dict[str, ContactSeries] = field(default_factory=dict)
    motor_t: FloatArray = field(default_factory=_empty)  # motor_state stamps [s]
    energy_consumed: FloatArray = field(default_factory=_empty)  # [J]
    energy_net: FloatArray = field(default_factory=_empty)  # [J]
    copper_loss: FloatArray = field(default_factory=_empty)  # [J]
    topic_counts: dict[str, int] = field(default_factory=dict)  # messages per topic


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


def read_series(bag: str | Path) -> BagSeries:
    """Read a recorded run into time series. Raises BagReadError if unreadable."""
    path = resolve_bag(Path(bag))
    joint: list[tuple[int, Any]] = []
    wrenches: dict[str, list[tuple[int, tuple[float, float, float]]]] = {}
    description: str | None = None
    ctrl: list[tuple[int, Any]] = []
    contacts: list[tuple[int, Any]] = []
    motor: list[tuple[int, float, float, float]] = []
    counts: dict[str, int] = {}
    try:
        with AnyReader([path]) as reader:
            for conn in reader.connections:
                counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount
            wanted = [
                c
                for c in reader.connections
                if c.msgtype in (_JOINT_STATE, _CONTACTS, _CONTROLLER_STATE, _MOTOR_STATE)
                or (c.msgtype == _WRENCH and _WRENCH_TOPIC in c.topic)
                or (c.msgtype == _STRING and c.topic.endswith(_DESCRIPTION_TOPIC))
            ]
            for conn, _, raw in reader.messages(connections=wanted):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                if conn.msgtype == _STRING:
                    description = description or str(msg.data)
                    continue
                stamp = _stamp_ns(msg)
                if conn.msgtype == _JOINT_STATE:
                    joint.append((stamp, msg))
                elif conn.msgtype == _WRENCH:
                    name = conn.topic.rsplit(_WRENCH_TOPIC, 1)[1]
                    wrenches.setdefault(name, []).append((stamp, _xyz(msg.wrench.force)))
                elif conn.msgtype == _CONTROLLER_STATE:
                    ctrl.append((stamp, msg))
                elif conn.msgtype == _CONTACTS:
                    contacts.append((stamp, msg))
                else:
                    motor.append((stamp, float(msg.energy_consumed), float(msg.energy_net), float(msg.copper_loss)))
    except BagReadError:
        raise
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        msg = f"cannot read bag {path}: {exc}"
        raise BagReadError(msg) from exc

    joint.sort(key=lambda x: x[0])
    ctrl.sort(key=lambda x: x[0])
    contacts.sort(key=lambda x: x[0])
    motor.sort(key=lambda x: x[0])
    if joint:
        t0 = joint[0][0]
    else:
        firsts = [lst[0][0] for lst in (ctrl, contacts, motor) if lst]
        t0 = min(firsts) if firsts else 0

    def sec(ns: int) -> float:
        return (ns - t0) * 1e-9

    series = BagSeries(t0_ns=t0, topic_counts=counts, robot_description=description)
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

    # Per contact, from the simulator.
    sim_rows: dict[str, list[tuple[int, float, float, float, bool, tuple[float, ...], tuple[float, ...]]]] = {}
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


def _by_name(msg: Any, names: list[str]) -> list[float]:
    """A JointState's positions in the order of ``names`` (NaN for a joint it lacks)."""
    if list(msg.name) == names:
        return [float(v) for v in msg.position]
    value = dict(zip(msg.name, msg.position, strict=False))
    return [float(value.get(n, math.nan)) for n in names]


def _rms(values: FloatArray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def compute_summary(series: BagSeries, wall_time_s: float | None = None) -> dict[str, Any]:
    """The summary.json dict (keys: SUMMARY_KEYS, in that order).

    A value that the recorded data cannot give (e.g. no controller_state after 2 s, no
    motor_state) is None; the contact-related values are 0.0 for a run without contacts.
    """
    out: dict[str, Any] = dict.fromkeys(SUMMARY_KEYS)

    mask = series.t >= HAND_ERROR_T_MIN_S - 1e-9
    if np.any(mask):
        err = np.linalg.norm(series.hand_desired[mask] - series.hand_actual[mask], axis=1)
        out["hand_rms_error_m"] = _rms(err)
        out["hand_max_error_m"] = float(np.max(err))

    contacts = list(series.contacts.values())
    if not contacts:
        out["brace_rms_error_m"] = 0.0
        out["normal_force_rms_error_n"] = 0.0
        out["constraint_residual_max_m"] = 0.0
    else:
        brace = np.concatenate([np.linalg.norm(c.brace_desired - c.brace_actual, axis=1) for c in contacts])
        brace = brace[np.isfinite(brace)]
        if brace.size:
            out["brace_rms_error_m"] = _rms(brace)
        force = np.concatenate([c.normal_force_error for c in contacts])
        force = force[np.isfinite(force)]
        if force.size:
            out["normal_force_rms_error_n"] = _rms(force)
        residual = np.concatenate([c.residual for c in contacts])
        if residual.size:
            out["constraint_residual_max_m"] = float(np.max(np.abs(residual)))

    if series.motor_t.size:
        out["energy_consumed_j"] = float(series.energy_consumed[-1])
        out["copper_loss_j"] = float(series.copper_loss[-1])

    if series.joint_t.size:
        out["sim_time_s"] = float(series.joint_t[-1] - series.joint_t[0])
    if wall_time_s is not None:
        out["wall_time_s"] = float(wall_time_s)
        if out["sim_time_s"] is not None and wall_time_s > 0:
            out["real_time_factor"] = out["sim_time_s"] / float(wall_time_s)
    return out
