"""A plain reference of ``bracing_analysis.bag.read_series``, for test_columns and the summary tests.

Written to be read, not to be fast: every message of the streams is decoded by rosbags' own
deserializer, one by one, and the series built from Python lists (``bag.read_series`` decodes them
column-wise, ``columns``). The events and the ground truth are read as ``bag`` reads them (rosbags
decodes those one by one there too). The same bag must give the same series, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader

from bracing_analysis.bag import (
    WRENCH_TOPIC,
    BagReadError,
    by_name,
    deepest_links,
    read_ground_truth,
    resolve_bag,
    wanted_connections,
)
from bracing_analysis.bag_events import RunEvents, read_events, xyz
from bracing_analysis.series import BagSeries, ContactSeries, LinkPenetrationSeries
from bracing_core.contact_roles import LINK_PENETRATION_TOPIC
from bracing_core.stamps import stamp_ns
from bracing_core.typestore import CONTACTS, CONTROLLER_STATE, JOINT_STATE, MOTOR_COMMAND, STRING, WRENCH_STAMPED

_Xyz = tuple[float, ...]


def read_series(bag: str | Path) -> BagSeries:
    """``bag.read_series`` with the streams decoded message by message."""
    path = resolve_bag(Path(bag))
    streams, events = _read(path)
    series = _series(streams)
    events.apply(series, path)
    deepest_links(series, recorded=bool(streams.penetration))  # from the series: the same code as bag's
    read_ground_truth(series, path)
    return series


@dataclass
class _Streams:
    """The decoded messages, by kind, in bag order, with their header stamps [ns]."""

    counts: dict[str, int] = field(default_factory=dict)
    joint: list[tuple[int, Any]] = field(default_factory=list)
    wrenches: dict[str, list[tuple[int, tuple[float, float, float]]]] = field(default_factory=dict)
    description: str | None = None
    ctrl: list[tuple[int, Any]] = field(default_factory=list)
    contacts: list[tuple[int, Any]] = field(default_factory=list)
    penetration: list[tuple[int, Any]] = field(default_factory=list)  # link_penetration
    motor: list[tuple[int, Any]] = field(default_factory=list)
    commands: list[tuple[int, Any]] = field(default_factory=list)


def _read(path: Path) -> tuple[_Streams, RunEvents]:
    streams = _Streams()
    try:
        with AnyReader([path]) as reader:
            wanted = wanted_connections(reader, streams.counts)
            events = read_events(reader)
            for conn, _, raw in reader.messages(connections=wanted):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                if conn.msgtype == STRING:
                    streams.description = streams.description or str(msg.data)
                    continue
                stamp = stamp_ns(msg.header.stamp)
                if conn.msgtype == JOINT_STATE:
                    streams.joint.append((stamp, msg))
                elif conn.msgtype == WRENCH_STAMPED:
                    name = conn.topic.rsplit(WRENCH_TOPIC, 1)[1]
                    streams.wrenches.setdefault(name, []).append((stamp, xyz(msg.wrench.force)))
                elif conn.msgtype == CONTROLLER_STATE:
                    streams.ctrl.append((stamp, msg))
                elif conn.msgtype == CONTACTS and conn.topic.endswith("/" + LINK_PENETRATION_TOPIC):
                    streams.penetration.append((stamp, msg))
                elif conn.msgtype == CONTACTS:
                    streams.contacts.append((stamp, msg))
                elif conn.msgtype == MOTOR_COMMAND:
                    streams.commands.append((stamp, msg))
                else:
                    streams.motor.append((stamp, msg))
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        msg = f"cannot read bag {path}: {exc}"
        raise BagReadError(msg) from exc
    for messages in (
        streams.joint,
        streams.ctrl,
        streams.contacts,
        streams.penetration,
        streams.motor,
        streams.commands,
    ):
        messages.sort(key=lambda x: x[0])
    return streams, events


def _series(streams: _Streams) -> BagSeries:
    joint, ctrl, motor = streams.joint, streams.ctrl, streams.motor
    if joint:
        t0 = joint[0][0]
    else:
        firsts = [lst[0][0] for lst in (ctrl, streams.contacts, motor) if lst]
        t0 = min(firsts) if firsts else 0

    def sec(ns: int) -> float:
        return (ns - t0) * 1e-9

    series = BagSeries(t0_ns=t0, topic_counts=streams.counts, robot_description=streams.description)
    series.joint_t = np.array([sec(s) for s, _ in joint], dtype=float)
    if joint:
        series.joint_names = [str(n) for n in joint[0][1].name]
        series.joint_position = np.array([by_name(m, series.joint_names) for _, m in joint], dtype=float)
    series.t = np.array([sec(s) for s, _ in ctrl], dtype=float)
    series.hand_desired = np.array([xyz(m.hand_desired) for _, m in ctrl], dtype=float).reshape(-1, 3)
    series.hand_actual = np.array([xyz(m.hand_actual) for _, m in ctrl], dtype=float).reshape(-1, 3)
    if motor:
        energies = [(float(m.energy_consumed), float(m.energy_net), float(m.copper_loss)) for _, m in motor]
        arr = np.array(energies, dtype=float)
        series.motor_t = np.array([sec(s) for s, _ in motor], dtype=float)
        series.energy_consumed, series.energy_net, series.copper_loss = arr[:, 0], arr[:, 1], arr[:, 2]
        series.motor_names = [str(n) for n in motor[0][1].name]
        width = len(series.motor_names)
        temperatures = [list(getattr(m, "temperature", ())) for _, m in motor]
        if any(len(row) == width > 0 for row in temperatures):
            series.motor_temperature = np.array(
                [row if len(row) == width else [math.nan] * width for row in temperatures], dtype=float
            )
    if streams.commands:  # by motor_state's names, else the first command's
        names = series.motor_names or [str(n) for n in streams.commands[0][1].name]
        values = [dict(zip(m.name, m.value, strict=False)) for _, m in streams.commands]
        series.command = np.array([[v.get(n, math.nan) for n in names] for v in values], dtype=float)
    _contacts(series, streams, sec)
    _link_penetration(series, streams, sec)
    return series


def _link_penetration(series: BagSeries, streams: _Streams, sec: Any) -> None:
    """Per surface (the part of each name after @), its rows of link_penetration in stamp order."""
    rows: dict[str, list[Any]] = {}
    for stamp, msg in streams.penetration:
        for c in msg.contacts:
            rows.setdefault(str(c.name).rsplit("@", 1)[-1], []).append((stamp, c))
    for surface, found in rows.items():
        series.link_penetration[surface] = LinkPenetrationSeries(
            name=str(found[0][1].name),
            t=np.array([sec(stamp) for stamp, _ in found], dtype=float),
            link=[str(c.frame) for _, c in found],
            inside=np.array([bool(c.active) for _, c in found], dtype=bool),
            position=np.array([xyz(c.position) for _, c in found], dtype=float).reshape(-1, 3),
            normal=np.array([xyz(c.normal) for _, c in found], dtype=float).reshape(-1, 3),
            distance=np.array([float(c.residual) for _, c in found], dtype=float),
        )


def _contacts(series: BagSeries, streams: _Streams, sec: Any) -> None:
    # Per contact, from the simulator.
    sim_rows: dict[str, list[tuple[int, float, float, float, bool, _Xyz, _Xyz, _Xyz]]] = {}
    for stamp, msg in streams.contacts:
        for c in msg.contacts:
            sim_rows.setdefault(str(c.name), []).append(
                (
                    stamp,
                    float(c.normal_force),
                    float(c.friction_force),
                    float(c.residual),
                    bool(c.active),
                    xyz(c.position),
                    xyz(c.normal),
                    xyz(c.slip_velocity),
                )
            )
    # Per contact, from the controller.
    ctrl_rows: dict[str, list[tuple[int, float, tuple[float, ...], tuple[float, ...]]]] = {}
    for stamp, msg in streams.ctrl:
        names = list(msg.contact_name)
        for j, name in enumerate(names):
            fnd = float(msg.desired_normal_force[j]) if j < len(msg.desired_normal_force) else math.nan
            bd = xyz(msg.brace_desired[j]) if j < len(msg.brace_desired) else (math.nan,) * 3
            ba = xyz(msg.brace_actual[j]) if j < len(msg.brace_actual) else (math.nan,) * 3
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
        forces = sorted(streams.wrenches.get(name, []))
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
