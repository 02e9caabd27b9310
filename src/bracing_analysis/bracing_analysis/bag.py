"""A recorded run's bag read into time series (``read_series``; no rclpy needed).

``read_series(bag)`` reads a rosbag2 bag (any storage) with rosbags' AnyReader, using only the message
definitions embedded in the bag, and returns a ``series.BagSeries`` (and the URDF of
``robot_description``, if the bag has it, for drawing the arm). The streams (joint_states, contacts,
link_penetration, controller_state, motor_state, the contact wrenches) are decoded column-wise (``columns``): a 10 s bag
(50k messages) reads in 0.25 s instead of the 1.5 s of rosbags' per-message deserializer, best of 3
(rosbags' reading is 0.2 s of it). The few other messages are decoded one by one (``bag_events``).
test/reference_series.py keeps the per-message reading as the reference the tests compare against.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader

from bracing_analysis.bag_events import custom_data, read_events
from bracing_analysis.columns import Layout, column, decode
from bracing_analysis.link_depths import every_link_deepest
from bracing_analysis.series import BagSeries, ContactSeries, FloatArray, LinkPenetrationSeries
from bracing_analysis.truth import (
    HAND,
    TASK_FRAMES_KEY,
    is_ground_truth,
    task_frames_from_json,
    true_positions,
)
from bracing_analysis.wrench_contacts import contacts_from_wrenches
from bracing_core.contact_roles import LINK_PENETRATION_TOPIC, surface_owner
from bracing_core.stamps import ns_of, stamp_ns
from bracing_core.targets import ORIENTATION_ERROR_TOPIC
from bracing_core.typestore import (
    CONTACTS,
    CONTROLLER_STATE,
    JOINT_STATE,
    MOTOR_COMMAND,
    MOTOR_STATE,
    STRING,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)

WRENCH_TOPIC = "contact_wrench/"
DESCRIPTION_TOPIC = "robot_description"

_Seconds = Callable[[NDArray[np.int64]], FloatArray]
_Kind = tuple[str, str]


class BagReadError(RuntimeError):
    """The bag is missing or cannot be read."""


def resolve_bag(path: Path) -> Path:
    """The bag directory: `path` itself, or `path/bag` when given the run directory."""
    if not path.exists():
        msg = f"bag not found: {path}"
        raise BagReadError(msg)
    if path.is_dir() and not (path / "metadata.yaml").exists() and (path / "bag").is_dir():
        return path / "bag"
    return path


def read_series(bag: str | Path, then: Callable[[BagSeries, AnyReader], None] | None = None) -> BagSeries:
    """Read a recorded run into time series. Raises BagReadError if unreadable.

    A robot that publishes no ``contacts`` (a ros2_control robot's, ``--engine mujoco``) gets each
    contact's series from its wrench (``wrench_contacts``). ``then(series, reader)``, if given, is called
    with the series and the bag still open: a reader of every message (bracing-view's replay) opens the
    bag once; what it raises is its own (not a BagReadError)."""
    path = resolve_bag(Path(bag))
    with _opened(path) as reader:
        series = _read_streams(path, reader)
        read_ground_truth(series, path, reader)
        contacts_from_wrenches(series)
        if then is not None:
            then(series, reader)
    return series


def topic_counts(bag: str | Path) -> dict[str, int]:
    """Every topic's message count, from the bag's metadata (no message read). Raises BagReadError."""
    counts: dict[str, int] = {}
    with _opened(resolve_bag(Path(bag))) as reader:
        _count(reader, counts)
    return counts


@contextmanager
def _opened(path: Path) -> Iterator[AnyReader]:
    """The bag open for reading (rosbags' AnyReader: the definitions embedded in it); BagReadError if it
    cannot be opened."""
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        raise BagReadError(f"cannot read bag {path}: {exc}") from exc
    try:
        yield reader
    finally:
        reader.close()


def read_ground_truth(series: BagSeries, path: Path, reader: AnyReader | None = None) -> None:
    """With sensors (truth.py): the task positions from ground_truth/joint_states, the controller's beside them
    (read with ``reader``, the bag open already, or opening it)."""
    if not any(is_ground_truth(topic) and topic.endswith("/joint_states") for topic in series.topic_counts):
        return
    frames = task_frames_from_json(custom_data(path).get(TASK_FRAMES_KEY, ""))
    if not frames or not series.robot_description:
        return  # a bag without the task frames: the controller's view is all there is
    stamps: list[int] = []
    rows: list[list[float]] = []
    names: list[str] = []
    if reader is None:
        with _opened(path) as opened:
            read_ground_truth(series, path, opened)
        return
    try:
        wanted = [c for c in reader.connections if is_ground_truth(c.topic) and c.msgtype == JOINT_STATE]
        for conn, _, raw in reader.messages(connections=wanted):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            names = names or list(msg.name)
            stamps.append(stamp_ns(msg.header.stamp))
            rows.append(by_name(msg, names))
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


def wanted_connections(reader: AnyReader, counts: dict[str, int]) -> list[Any]:
    """The connections read_series decodes (and every topic's message count into ``counts``)."""
    _count(reader, counts)
    return [
        c
        for c in reader.connections
        if not is_ground_truth(c.topic)  # read_ground_truth's, after the rest
        and (
            c.msgtype in (JOINT_STATE, CONTACTS, CONTROLLER_STATE, MOTOR_STATE, MOTOR_COMMAND)
            or (c.msgtype == WRENCH_STAMPED and WRENCH_TOPIC in c.topic)
            or (c.msgtype == STRING and c.topic.endswith(DESCRIPTION_TOPIC))
            or (c.msgtype == VECTOR3_STAMPED and c.topic.endswith("/" + ORIENTATION_ERROR_TOPIC))
        )
    ]


def _count(reader: AnyReader, counts: dict[str, int]) -> None:
    """Every topic's message count (the bag's metadata) added into ``counts``."""
    for conn in reader.connections:
        counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount


def _kind(conn: Any) -> tuple[str, str]:
    """What the messages are grouped by: the type, and the contact of a wrench topic (link_penetration apart)."""
    if conn.msgtype == CONTACTS and conn.topic.endswith("/" + LINK_PENETRATION_TOPIC):
        return (CONTACTS, LINK_PENETRATION_TOPIC)  # the links against the surfaces: not the contacts
    return (conn.msgtype, conn.topic.rsplit(WRENCH_TOPIC, 1)[1] if conn.msgtype == WRENCH_STAMPED else "")


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
    stamp = ns_of(sec, column(layouts, "header.stamp.nanosec", count).astype(np.int64))
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

    def texts(self, path: str) -> list[str]:
        """The string at ``path`` (``{j}``: the contact's position) of each row."""
        parts = [np.full(len(lay.index), lay.strings[path.format(j=j)], dtype=object) for lay, j in self.entries]
        return [str(text) for text in np.concatenate(parts)[self.perm]]


def _per_contact(messages: _Messages, sequence: str, name: str, key: Callable[[str], str] = str) -> dict[str, _Rows]:
    """``key`` of the contact name -> its rows; ``name`` is the path of a contact's name (``{j}``: its position)."""
    entries: dict[str, list[tuple[Layout, int]]] = {}
    for layout in messages.layouts:
        for j in range(layout.lengths[sequence]):
            entries.setdefault(key(layout.strings[name.format(j=j)]), []).append((layout, j))
    rows = {}
    for contact, found in entries.items():
        index = np.concatenate([layout.index for layout, _ in found])
        slot = np.concatenate([np.full(len(layout.index), j) for layout, j in found])
        perm = np.lexsort((slot, messages.rank[index]))
        first = (int(messages.rank[index[perm[0]]]), int(slot[perm[0]]))
        rows[contact] = _Rows(found, perm, messages.stamp[index][perm], first)
    # Contacts in the order they first appear (in stamp order, then order in the message).
    return dict(sorted(rows.items(), key=lambda item: item[1].first))


def _joint_positions(joint: _Messages, names: list[str], field: str = "position") -> FloatArray:
    """by_name per layout: every JointState's positions (or MotorCommand's ``value``s) in the order of ``names``."""
    blocks: list[tuple[Layout, list[str | None]]] = []
    for layout in joint.layouts:
        count, own = layout.lengths[field], layout.texts("name")
        if own == names:
            paths: list[str | None] = [f"{field}[{j}]" for j in range(count)]
        else:  # as by_name's dict: zip stops at the shorter list, a repeated name's last position wins
            where = dict(zip(own, range(count), strict=False))
            paths = [f"{field}[{where[n]}]" if n in where else None for n in names]
        blocks.append((layout, paths))
    widths = {len(paths) for _, paths in blocks}
    if len(widths) > 1:  # what np.array raises on ragged rows (the per-message reading)
        msg = "JointState messages with different numbers of positions"
        raise ValueError(msg)
    out = np.empty((joint.count, widths.pop()))
    for layout, paths in blocks:
        for k, path in enumerate(paths):
            out[layout.index, k] = math.nan if path is None else layout.values[path]
    return out[joint.order]


def _commands(command: _Messages, names: list[str]) -> FloatArray:
    """Every motor_command's values by ``names`` (motor_state's: the model's order; none: the first command's);
    empty where there are none or they disagree in length (saturation_fraction is then null)."""
    if not command.count:
        return np.zeros((0, 0))
    first = next(layout for layout in command.layouts if np.any(layout.index == command.order[0]))
    try:
        return _joint_positions(command, names or first.texts("name"), "value")
    except ValueError:
        return np.zeros((0, 0))


def _motor_temperatures(motor: _Messages) -> tuple[list[str], FloatArray]:
    """The motor names and temperatures: the first message's names (in stamp
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


def _read_streams(path: Path, reader: AnyReader) -> BagSeries:
    """The bag's streams (each kind of message decoded column-wise, ``columns.decode``) and events."""
    counts: dict[str, int] = {}
    kinds = (JOINT_STATE, CONTROLLER_STATE, CONTACTS, MOTOR_STATE, MOTOR_COMMAND)
    raws: dict[_Kind, list[bytes]] = {(t, ""): [] for t in kinds}
    try:
        wanted = wanted_connections(reader, counts)
        events = read_events(reader)
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
    series = _series(messages, texts, counts)
    events.apply(series, path)
    deepest_links(series, recorded=(CONTACTS, LINK_PENETRATION_TOPIC) in messages)
    return series


def deepest_links(series: BagSeries, recorded: bool) -> None:
    """``series.link_penetration_max`` of a run whose bag has link_penetration messages (``recorded``; else it
    stays None): every moving link's deepest (``link_depths``) where the bag has what it takes (the URDF, the
    postures, the surfaces) and this machine the meshes; else the topic's (``series.link_penetration``: each
    surface's deepest link at each state). Both bag readers (this one and the tests' per-message reference)
    call it on the series they read, after its events (the surfaces)."""
    if not recorded:
        return
    series.link_penetration_max = _topic_depths(series.link_penetration)
    if not series.robot_description or not series.surfaces:
        return
    try:
        every = every_link_deepest(series.robot_description, series.joint_names, series.joint_position, series.surfaces)
    except ValueError:
        return
    if not every:  # the URDF as recorded has no moving link with shapes: the topic's links are all there is
        return
    topic = series.link_penetration_max
    series.link_penetration_max = {link: max(depth, topic.get(link, 0.0)) for link, depth in every.items()}


def _series(messages: dict[_Kind, _Messages], texts: list[Layout], counts: dict[str, int]) -> BagSeries:
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
    series = BagSeries(t0_ns=t0, topic_counts=counts, robot_description=description)
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
    series.command = _commands(messages[(MOTOR_COMMAND, "")], series.motor_names)
    turn = messages.get((VECTOR3_STAMPED, ""))
    if turn is not None and turn.count:
        series.hand_orientation_error = _per_state_row(turn, ctrl, "vector")
    sim_rows = _per_contact(sim, "contacts", "contacts[{j}].name")
    ctrl_rows = _per_contact(ctrl, "contact_name", "contact_name[{j}]")
    for name in list(sim_rows) + [n for n in ctrl_rows if n not in sim_rows]:
        wrench = messages.get((WRENCH_STAMPED, name))
        series.contacts[name] = _contact(name, sim_rows.get(name), wrench, ctrl_rows.get(name), sec)
    measured = messages.get((CONTACTS, LINK_PENETRATION_TOPIC))
    if measured is not None and measured.count:
        by_surface = _per_contact(measured, "contacts", "contacts[{j}].name", key=surface_owner)
        series.link_penetration = {owner: _link_penetration(rows, sec) for owner, rows in by_surface.items()}
    return series


def _link_penetration(rows: _Rows, sec: _Seconds) -> LinkPenetrationSeries:
    """One surface's rows of ``link_penetration``: the link deepest in or nearest to it at each state."""
    return LinkPenetrationSeries(
        name=rows.texts("contacts[{j}].name")[0],
        t=sec(rows.stamp),
        link=rows.texts("contacts[{j}].frame"),
        inside=rows.take("contacts[{j}].active").astype(bool),
        position=rows.xyz("contacts[{j}].position"),
        normal=rows.xyz("contacts[{j}].normal"),
        distance=rows.take("contacts[{j}].residual").astype(float),
    )


def _topic_depths(measured: dict[str, LinkPenetrationSeries]) -> dict[str, float]:
    """Per link the link_penetration topic names (its ``frame``, the link deepest into or nearest a surface at a
    state): the deepest it was inside a surface [m] at those states (0: never inside)."""
    out: dict[str, float] = {}
    for surface in measured.values():
        for link, distance in zip(surface.link, surface.distance.tolist(), strict=True):
            depth = 0.0 if math.isnan(distance) else max(0.0, -distance)
            out[link] = max(out.get(link, 0.0), depth)
    return out


def _per_state_row(messages: _Messages, ctrl: _Messages, path: str) -> FloatArray:
    """The vector at ``path`` of ``messages`` (stamped with the state they answer) on each controller_state row,
    by stamp (the last of a stamp; NaN where a row has none)."""
    stamps, values = messages.stamp[messages.order], messages.xyz(path)
    rows = ctrl.stamp[ctrl.order]
    at = np.searchsorted(stamps, rows, side="right") - 1
    found = (at >= 0) & (stamps[np.clip(at, 0, None)] == rows)
    out = np.full((rows.size, 3), math.nan)
    out[found] = values[at[found]]
    return out


def _contact(
    name: str, rows: _Rows | None, wrench: _Messages | None, crow: _Rows | None, sec: _Seconds
) -> ContactSeries:
    """One contact's series: its rows of contacts (``rows``), its wrench messages, its rows of controller_state."""
    cs = ContactSeries(name=name)
    if rows is not None:
        cs.t = sec(rows.stamp)
        cs.normal_force = rows.take("contacts[{j}].normal_force").astype(float)
        cs.friction_force = rows.take("contacts[{j}].friction_force").astype(float)
        cs.residual = rows.take("contacts[{j}].residual").astype(float)
        cs.active = rows.take("contacts[{j}].active").astype(bool)
        cs.position = rows.xyz("contacts[{j}].position")
        cs.normal = rows.xyz("contacts[{j}].normal")
        cs.slip_velocity = rows.xyz("contacts[{j}].slip_velocity")
    if wrench is not None and wrench.count:
        force = [column(wrench.layouts, f"wrench.force.{axis}", wrench.count).astype(float) for axis in "xyz"]
        by_force = np.lexsort((*force[::-1], wrench.stamp))  # as sorted() of (stamp, force) tuples
        cs.t_force = sec(wrench.stamp[by_force])
        cs.force = np.stack(force, axis=1)[by_force]
    if crow is not None:
        cs.t_ctrl = sec(crow.stamp)
        cs.normal_force_desired = crow.take("desired_normal_force[{j}]").astype(float)
        cs.brace_desired = crow.xyz("brace_desired[{j}]")
        cs.brace_actual = crow.xyz("brace_actual[{j}]")
        if rows is not None:
            stamps, cs.normal_force_error = _match(rows, crow)
            cs.t_matched = sec(stamps)
    return cs


def by_name(msg: Any, names: list[str]) -> list[float]:
    """A JointState's positions in the order of ``names`` (NaN for a joint it lacks)."""
    if list(msg.name) == names:
        return [float(v) for v in msg.position]
    value = dict(zip(msg.name, msg.position, strict=False))
    return [float(value.get(n, math.nan)) for n in names]
