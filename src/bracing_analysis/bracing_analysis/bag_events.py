"""What a run's bag holds besides its streams: the few messages rosbags decodes one by one (the targets
sent, the parameter changes, the nodes' warnings, the input mode) and the metadata the recorder noted
(scenario, surfaces, task axes). ``read_events`` reads them, ``RunEvents.apply`` puts them in a series."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from rosbags.highlevel import AnyReader

from bracing_analysis.series import BagSeries, ParameterChange, TargetRefused, TargetSent
from bracing_analysis.surfaces import SCENARIO_KEY, SURFACES_KEY, from_json
from bracing_analysis.truth import (
    COMMAND_LIMIT_KEY,
    INPUT_MODE_KEY,
    TASK_AXES_KEY,
    command_limits_from_json,
    task_axes_from_json,
)
from bracing_core.stamps import stamp_ns
from bracing_core.targets import ACCEPTED, POSE_TOPIC, REFUSED, REFUSED_COUNT_KEY, REFUSED_KIND_KEY
from bracing_core.typestore import (
    DIAGNOSTIC_STATUS,
    MOTOR_COMMAND,
    PARAMETER_EVENT,
    PATH,
    POINT_STAMPED,
    POSE_STAMPED,
    RUN_STATUS,
    motor_command_modes,
)

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

INPUT_MODES = ("voltage", "torque")
"""The controller's input modes (its ``input_mode`` parameter's choices)."""

_Target = tuple[int, str, list[tuple[float, float, float]], list[int]]
_Refused = tuple[int, str, str, str, int]  # bag time [ns], topic, kind, why, refused on the topic so far
_ParameterEvent = tuple[int, str, dict[str, Any]]


def xyz(point: Any) -> tuple[float, float, float]:
    return (float(point.x), float(point.y), float(point.z))


@dataclass(frozen=True)
class RunEvents:
    """The run's events at their bag times [ns] (the time base is the series' ``t0_ns``)."""

    input_mode: str | None
    parameter_events: list[_ParameterEvent]
    warnings: list[str]
    targets: list[_Target]
    refused: list[_Refused]

    def apply(self, series: BagSeries, path: Path) -> None:
        """Into ``series`` (its ``t0_ns`` set): these events, and the bag's metadata (``describe``)."""
        t0 = series.t0_ns
        series.input_mode = self.input_mode
        series.parameter_changes = [
            ParameterChange((stamp - t0) * 1e-9, node, values) for stamp, node, values in self.parameter_events
        ]
        series.warnings = self.warnings
        series.targets = [
            TargetSent(
                (stamp - t0) * 1e-9,
                task,
                np.array(points, dtype=float).reshape(-1, 3),
                ((np.array(times, dtype=np.int64) - t0) * 1e-9).astype(np.float64),
            )
            for stamp, task, points, times in self.targets
        ]
        series.targets_refused = [
            TargetRefused((stamp - t0) * 1e-9, topic, kind, why, count)
            for stamp, topic, kind, why, count in self.refused
        ]
        describe(series, path)


def read_events(reader: AnyReader) -> RunEvents:
    return RunEvents(
        _input_mode(reader), _parameter_events(reader), _recorded_warnings(reader), _targets(reader), _refused(reader)
    )


def _decoded(reader: AnyReader, wanted: Callable[[Any], bool]) -> Iterator[tuple[Any, int, Any]]:
    """(connection, bag time [ns], message) of the ``wanted`` connections' messages, in bag order."""
    connections = [c for c in reader.connections if wanted(c)]
    if not connections:  # (an empty list would make reader.messages read every topic)
        return
    for conn, stamp, raw in reader.messages(connections=connections):
        yield conn, stamp, reader.deserialize(raw, conn.msgtype)


def _input_mode(reader: AnyReader) -> str | None:
    """The mode of the first motor_command (the controller sends one mode for a whole run); None if
    none was recorded or the mode is not one MotorCommand defines."""
    for _, _, command in _decoded(reader, lambda c: c.msgtype == MOTOR_COMMAND):
        names = {code: name for name, code in motor_command_modes(reader.typestore).items()}  # the bag's .msg
        return names.get(int(command.mode))
    return None


def custom_data(path: Path) -> dict[str, str]:
    """The bag's metadata ``custom_data`` (what the recorder noted: scenario, surfaces, tasks); {} if none."""
    try:
        document = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
        data = document["rosbag2_bagfile_information"].get("custom_data") or {}
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def describe(series: BagSeries, path: Path) -> None:
    """The run's scenario, surfaces and task axes from the bag's metadata, into ``series``; and its input
    mode, should no motor_command say it (a ros2_control robot's run: the efforts go to its controller)."""
    data = custom_data(path)
    if series.input_mode is None and data.get(INPUT_MODE_KEY) in INPUT_MODES:
        series.input_mode = data[INPUT_MODE_KEY]
    series.scenario = data.get(SCENARIO_KEY) or None
    series.surfaces = from_json(data.get(SURFACES_KEY, "{}"))
    series.hand_axes, series.brace_task_axes = task_axes_from_json(data.get(TASK_AXES_KEY, "{}"))
    series.command_limit = command_limits_from_json(data.get(COMMAND_LIMIT_KEY, "{}"))


def _target_task(topic: str) -> str | None:
    """The task a target topic (resolved, namespaced or not) sends: "hand" or the contact's name; None for
    another topic."""
    if "brace_target/" in topic:
        return topic.split("brace_target/", 1)[1]
    return "hand" if topic.rsplit("/", 1)[-1] in ("hand_target", "hand_path", POSE_TOPIC) else None


def _targets(reader: AnyReader) -> list[_Target]:
    """(bag time [ns], task, points, pose stamps [ns]) of each target the controller accepted
    (``<target>/accepted``), in time order. A bag from before the controller said so (no verdict
    recorded, targets recorded) has those as sent."""
    verdicts = [c for c in reader.connections if c.topic.endswith((f"/{ACCEPTED}", f"/{REFUSED}"))]
    suffix = f"/{ACCEPTED}" if verdicts else ""

    def target(c: Any) -> bool:
        topic = c.topic.removesuffix(suffix) if c.topic.endswith(suffix) else ""
        return c.msgtype in (POINT_STAMPED, PATH, POSE_STAMPED) and topic != "" and _target_task(topic) is not None

    out: list[_Target] = []
    for conn, stamp, msg in _decoded(reader, target):
        task = str(_target_task(conn.topic.removesuffix(suffix)))
        if conn.msgtype == PATH:
            points = [xyz(pose.pose.position) for pose in msg.poses]
            times = [stamp_ns(pose.header.stamp) for pose in msg.poses]
        elif conn.msgtype == POSE_STAMPED:  # its position drawn (its orientation is in hand_orientation_error)
            points, times = [xyz(msg.pose.position)], [stamp]
        else:
            points, times = [xyz(msg.point)], [stamp]
        out.append((stamp, task, points, times))
    return sorted(out, key=lambda e: e[0])


def _refused(reader: AnyReader) -> list[_Refused]:
    """(bag time [ns], topic, kind, why, refused on that topic so far) of each target the controller
    refused (``<target>/refused``), in time order."""

    def wanted(c: Any) -> bool:
        return c.msgtype == DIAGNOSTIC_STATUS and c.topic.endswith(f"/{REFUSED}")

    out: list[_Refused] = []
    for _, stamp, status in _decoded(reader, wanted):
        values = {str(v.key): str(v.value) for v in status.values}
        count = int(values.get(REFUSED_COUNT_KEY, "0")) if values.get(REFUSED_COUNT_KEY, "").isdigit() else 0
        out.append((stamp, str(status.name), values.get(REFUSED_KIND_KEY, ""), str(status.message), count))
    return sorted(out, key=lambda e: e[0])


def _parameter_value(value: Any) -> Any:
    held = getattr(value, _VALUE_FIELDS.get(int(value.type), ""), None)
    return held.tolist() if isinstance(held, np.ndarray) else list(held) if isinstance(held, list) else held


def _parameter_events(reader: AnyReader) -> list[_ParameterEvent]:
    """(stamp [ns], node, {name: new value}) of each recorded /parameter_events message that changes
    or deletes a value (a few per run)."""
    out = []
    for _, _, event in _decoded(reader, lambda c: c.msgtype == PARAMETER_EVENT):
        values = {str(p.name): _parameter_value(p.value) for p in event.changed_parameters}
        values.update({str(p.name): None for p in event.deleted_parameters})
        if values:
            stamp = stamp_ns(event.stamp)
            out.append((stamp, str(event.node), values))
    return sorted(out, key=lambda e: e[0])


def _recorded_warnings(reader: AnyReader) -> list[str]:
    """The warnings the nodes said on run_status (the recorder keeps only those), in time order (a few per run)."""
    out = []
    for _, stamp, status in _decoded(reader, lambda c: c.msgtype == RUN_STATUS):
        if status.text:
            out.append((stamp, str(status.text)))
    return [text for _, text in sorted(out, key=lambda w: w[0])]
