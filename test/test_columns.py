"""Column-wise CDR decoding (columns.py) and read_series built on it.

The reference everywhere is rosbags' own deserializer: ``typestore.deserialize_cdr`` for
single messages, ``reference_series.read_series`` (every message deserialized by rosbags) for whole bags.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import reference_series
from rosbags.interfaces import Nodetype
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from bracing_analysis.bag import BagReadError, read_series
from bracing_analysis.columns import MAX_PROBES, Layout, decode
from bracing_analysis.summary import compute_summary
from bracing_core.typestore import bracing_typestore
from bracing_recorder.recorder import BAG_VERSION

OUR_TYPES = (
    "sensor_msgs/msg/JointState",
    "geometry_msgs/msg/WrenchStamped",
    "bracing_msgs/msg/Contacts",
    "bracing_msgs/msg/ControllerState",
    "bracing_msgs/msg/MotorState",
    "bracing_msgs/msg/MotorCommand",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/String",
)

# Awkward alignment: nested messages starting with a byte, empty sequences of doubles, strings
# of odd lengths, arrays of strings and of messages, every primitive.
ODD_MSGS = {
    "test_msgs/msg/Inner": "uint8 tag\nfloat64 value\nstring label\n",
    "test_msgs/msg/Odd": (
        "uint8 a\ntest_msgs/Inner[] inner\nfloat64[] b\nstring s\nint16 c\nbool[3] flags\n"
        "test_msgs/Inner fixed_inner\nuint8[] raw\nint64 big\nstring[2] pair\nfloat32 f\n"
        "test_msgs/Inner[2] two\nbyte by\nchar ch\nint8 i8\nuint16 u16\nint32 i32\nuint32 u32\n"
        "uint64 u64\nstring[<=3] bounded\nfloat64[<=2] short\n"
    ),
}


# --------------------------------------------------------------------------- helpers


def odd_typestore() -> Typestore:
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in ODD_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store


def random_message(store: Typestore, typename: str, rng: np.random.Generator) -> Any:
    """A message with random values; lengths and strings from small pools so that layouts repeat."""
    fields = {}
    for name, desc in store.get_msgdef(typename).fields:
        fields[name] = _random_field(store, desc, rng)
    return store.types[typename](**fields)


def _random_field(store: Typestore, desc: Any, rng: np.random.Generator) -> Any:
    kind, arg = desc
    if kind == Nodetype.NAME:
        return random_message(store, arg, rng)
    if kind == Nodetype.BASE:
        return _random_base(arg[0], rng)
    sub, size = arg
    count = size if kind == Nodetype.ARRAY else int(rng.integers(0, 3 if not size else size + 1))
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        dtype = {"bool": np.bool_, "char": np.uint8, "byte": np.int8}.get(sub[1][0], sub[1][0])
        return np.array([_random_base(sub[1][0], rng) for _ in range(count)], dtype=dtype)
    return [_random_field(store, sub, rng) for _ in range(count)]


def _random_base(typename: str, rng: np.random.Generator) -> Any:
    if typename == "string":
        return str(rng.choice(["", "a", "joint1", "é", "wrist"]))
    if typename == "bool":
        return bool(rng.integers(0, 2))
    if typename.startswith("float"):
        return float(
            rng.choice([rng.normal(), rng.normal(), -0.0, np.inf, np.nan, 1e300 if typename == "float64" else 1e30])
        )
    dtype = np.dtype({"char": np.uint8, "byte": np.int8}.get(typename, typename))
    info = np.iinfo(dtype)
    return int(rng.integers(info.min, info.max, endpoint=True, dtype=dtype))


def flatten(obj: Any, prefix: str, out: dict[str, Any]) -> dict[str, Any]:
    """path -> leaf of a message object, walked by its attributes (not by the definitions)."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            if "ClassVar" in str(f.type):  # __msgtype__ and constants
                continue
            flatten(getattr(obj, f.name), f"{prefix}.{f.name}" if prefix else f.name, out)
    elif isinstance(obj, (list, np.ndarray)):
        out[f"len {prefix}"] = len(obj)
        for i, item in enumerate(obj):
            flatten(item, f"{prefix}[{i}]", out)
    else:
        out[prefix] = obj
    return out


def check_decoded(store: Typestore, typename: str, raws: list[bytes], layouts: list[Layout]) -> None:
    """Every message of ``layouts`` equals rosbags' decoding of it, bit for bit."""
    indices = np.sort(np.concatenate([layout.index for layout in layouts]))
    assert np.array_equal(indices, np.arange(len(raws)))  # each message exactly once
    for layout in layouts:
        for row, k in enumerate(layout.index):
            expected = flatten(store.deserialize_cdr(raws[k], typename), "", {})
            got: dict[str, Any] = {f"len {p}": n for p, n in layout.lengths.items()}
            got.update(layout.strings)
            got.update({p: v[row] for p, v in layout.values.items()})
            assert sorted(got) == sorted(expected)
            for path, value in expected.items():
                if isinstance(value, str) or path.startswith("len "):
                    assert got[path] == value, path
                else:
                    column = layout.values[path]
                    # rosbags gives numpy scalars (arrays) or Python numbers: same bits in the column's type.
                    assert np.asarray(value, dtype=column.dtype).tobytes() == column[row].tobytes(), path
                    if isinstance(value, np.generic):
                        assert value.dtype == column.dtype, path


def same_series(a: Any, b: Any, where: str = "series") -> None:
    """Equal bit for bit (NaN where NaN), same dtypes and shapes, same dict orders."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray), where
        assert (a.dtype, a.shape) == (b.dtype, b.shape), where
        assert np.array_equal(a, b, equal_nan=True), where
    elif isinstance(a, dict):
        assert list(a) == list(b), where
        for key in a:
            same_series(a[key], b[key], f"{where}[{key!r}]")
    elif dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            same_series(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    else:
        assert type(a) is type(b) and a == b, where


def assert_columnar_is_general(bag: Path) -> Any:
    general, columnar = reference_series.read_series(bag), read_series(bag)
    same_series(general, columnar)
    assert json.dumps(compute_summary(general, 1.5)) == json.dumps(compute_summary(columnar, 1.5))  # NaN-safe
    return columnar


# --------------------------------------------------------------------------- columns.decode


@pytest.mark.parametrize("typename", [*OUR_TYPES, "test_msgs/msg/Odd"])
@pytest.mark.parametrize("max_probes", [MAX_PROBES, 0, 1000])
def test_decode_equals_rosbags_for_random_messages(typename: str, max_probes: int) -> None:
    store = odd_typestore() if typename.startswith("test_msgs") else bracing_typestore()
    rng = np.random.default_rng([len(typename), max_probes])
    raws = [
        bytes(store.serialize_cdr(random_message(store, typename, rng), typename, little_endian=k % 5 != 0))
        for k in range(150)
    ]
    layouts = decode(store, typename, raws, max_probes=max_probes)
    check_decoded(store, typename, raws, layouts)
    if max_probes == 0:
        assert len(layouts) == len(raws)
    elif max_probes == 1000:  # one layout per distinct (size, layout bytes) only
        assert len(layouts) < len(raws) or typename == "test_msgs/msg/Odd"


def test_decode_groups_messages_that_share_a_layout() -> None:
    store = bracing_typestore()
    joint = store.types["sensor_msgs/msg/JointState"]
    header = store.types["std_msgs/msg/Header"]
    time = store.types["builtin_interfaces/msg/Time"]

    def state(k: int, names: list[str]) -> bytes:
        values = np.arange(len(names), dtype=float) + k
        msg = joint(header(time(k, 7), "w"), names, values, values * 2, np.zeros(0))
        return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))

    # The same size, two layouts (names in another order), interleaved.
    raws = [state(k, ["j1", "j2"] if k % 3 else ["j2", "j1"]) for k in range(30)]
    layouts = decode(store, "sensor_msgs/msg/JointState", raws)
    assert [layout.texts("name") for layout in layouts] == [["j2", "j1"], ["j1", "j2"]]
    assert [layout.index.tolist() for layout in layouts] == [list(range(0, 30, 3)), [k for k in range(30) if k % 3]]
    assert layouts[1].lengths == {"name": 2, "position": 2, "velocity": 2, "effort": 0}
    assert layouts[1].values["velocity[1]"].tolist() == [2.0 * (k + 1) for k in range(30) if k % 3]
    assert layouts[1].values["header.stamp.sec"].dtype == np.int32
    check_decoded(store, "sensor_msgs/msg/JointState", raws, layouts)


def test_decode_raises_like_rosbags_on_a_damaged_message() -> None:
    store = bracing_typestore()
    good = bytes(
        store.serialize_cdr(
            random_message(store, "bracing_msgs/msg/Contacts", np.random.default_rng(1)), "bracing_msgs/msg/Contacts"
        )
    )
    bad = good[:12] + b"\xff\xff\xff\x7f" + good[16:]  # frame_id's length far beyond the message
    with pytest.raises(SerdeError):
        store.deserialize_cdr(bad, "bracing_msgs/msg/Contacts")
    with pytest.raises(SerdeError):
        decode(store, "bracing_msgs/msg/Contacts", [good, bad, good])


# --------------------------------------------------------------------------- read_series on synthetic bags


JOINTS = ["joint1", "joint2", "joint3", "joint4"]


class BagBuilder:
    """Messages of our types, serialized by rosbags (either byte order), written in call order."""

    def __init__(self) -> None:
        self.store = bracing_typestore()
        self.items: list[tuple[str, str, bytes]] = []
        self.v = 0.0  # what the values of the next messages derive from (not the stamp: stamps repeat)

    def t(self, ns: int) -> Any:
        return self.store.types["builtin_interfaces/msg/Time"](ns // 1_000_000_000, ns % 1_000_000_000)

    def header(self, ns: int, frame: str = "world") -> Any:
        return self.store.types["std_msgs/msg/Header"](self.t(ns), frame)

    def point(self, *xyz: float) -> Any:
        return self.store.types["geometry_msgs/msg/Point"](*xyz)

    def vector(self, *xyz: float) -> Any:
        return self.store.types["geometry_msgs/msg/Vector3"](*xyz)

    def add(self, topic: str, typename: str, msg: Any, little: bool = True) -> None:
        self.items.append((topic, typename, bytes(self.store.serialize_cdr(msg, typename, little_endian=little))))

    def joint(self, ns: int, names: list[str], little: bool = True) -> None:
        pos = np.array([0.1 * self.v + j for j in range(len(names))])
        msg = self.store.types["sensor_msgs/msg/JointState"](self.header(ns), names, pos, -pos, np.zeros(0))
        self.add("/joint_states", "sensor_msgs/msg/JointState", msg, little)

    def contacts(self, ns: int, names: list[str], little: bool = True) -> None:
        state = self.store.types["bracing_msgs/msg/ContactState"]
        f = self.v
        cs = [
            state(
                n,
                n + "_frame",
                bool((ns // 1_000_000 + j) % 3),
                self.point(j, f, 1e-3 * f),
                self.vector(0, 0, 1),
                10.0 + f + j,
                -f,
                self.vector(f, 0, 0),
                1e-6 * f * (j + 1),
            )
            for j, n in enumerate(names)
        ]
        msg = self.store.types["bracing_msgs/msg/Contacts"](self.header(ns), cs)
        self.add("/contacts", "bracing_msgs/msg/Contacts", msg, little)

    def controller(
        self, ns: int, names: list[str], forces: int, braces: int, little: bool = True, desired: float = 10.0
    ) -> None:
        f = self.v
        msg = self.store.types["bracing_msgs/msg/ControllerState"](
            self.header(ns),
            self.point(0, f, 1),
            self.point(0, f + 0.01, 1.0 - 0.5e-3 * f),
            names,
            np.full(forces, desired) + f % 3,
            [self.point(0, 0.5, j) for j in range(braces)],
            [self.point(0, 0.5 + 1e-3 * f, j) for j in range(braces)],
            np.array([f, -f]),
            1e-4,
        )
        self.add("/controller_state", "bracing_msgs/msg/ControllerState", msg, little)

    def motor(self, ns: int, frame: str, little: bool = True) -> None:
        f = self.v
        msg = self.store.types["bracing_msgs/msg/MotorState"](
            self.header(ns, frame),
            JOINTS,
            np.ones(4),
            np.ones(4) * f,
            np.ones(4),
            25.0 + 1e-3 * f * np.arange(1, 5),  # a winding temperature per joint [degC]
            2.0 * f,
            1.5 * f,
            0.5 * f,
        )
        self.add("/motor_state", "bracing_msgs/msg/MotorState", msg, little)

    def wrench(self, ns: int, name: str, fz: float, little: bool = True) -> None:
        w = self.store.types["geometry_msgs/msg/Wrench"](self.vector(0, -fz / 10, fz), self.vector(0, 0, 0))
        msg = self.store.types["geometry_msgs/msg/WrenchStamped"](self.header(ns), w)
        self.add(f"/contact_wrench/{name}", "geometry_msgs/msg/WrenchStamped", msg, little)

    def description(self, text: str) -> None:
        self.add("/robot_description", "std_msgs/msg/String", self.store.types["std_msgs/msg/String"](text))

    def write(self, bag: Path) -> Path:
        with Writer(bag, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
            conns: dict[str, Any] = {}
            for k, (topic, typename, raw) in enumerate(self.items):
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, typename, typestore=self.store)
                writer.write(conns[topic], k, raw)
        return bag


def varying_bag(path: Path, with_joints: bool = True) -> Path:
    """Layouts that change inside each topic, stamps out of order and repeated, both byte orders."""
    b = BagBuilder()
    b.description("")
    ms = 1_000_000
    stamps = [k * ms for k in range(120)]
    stamps[5], stamps[6] = stamps[6], stamps[5]  # out of order
    stamps[40] = stamps[39]  # repeated
    stamps[60:90] = [ms * (60 + (89 - k) // 3 * 3) for k in range(60, 90)]  # backwards, in threes
    stamps[100:] = [stamps[100]] * 20  # many ties: the sort must keep bag order
    stamps[0] = 7 * ms  # the first message in the bag is not the first in time
    for k, ns in enumerate(stamps):
        b.v = k
        little = k % 7 != 3
        if with_joints:
            names = JOINTS if k < 50 or k % 4 else list(reversed(JOINTS))  # same size, other layout
            if 60 <= k < 70:
                names = ["joint1", "joint2", "joint5"]  # joints 3, 4 missing (NaN), an unknown one
            if k == 80:
                names = ["joint2", "joint2", "joint1", "joint3"]  # a repeated name: its last position counts
            b.joint(ns, names, little)
        contacts = ["elbow"] if k < 30 else ["elbow", "wrist"] if k < 90 else ["wrist", "elbow"]
        if k in (33, 34):
            contacts = []
        if k == 1:
            contacts = ["wrist"]  # first in time (its layout is not the first one decoded)
        if k == 100:
            contacts = ["elbow", "elbow"]  # one contact twice in one message
        b.contacts(ns, contacts, little)
        names = ["elbow"] if k < 30 else ["elbow", "wrist"]
        b.controller(
            ns, names, forces=0 if k % 10 == 5 else len(names), braces=1 if k % 9 == 0 else len(names), little=little
        )
        if k == 40:  # stamp 39 ms a third time, other forces: the last controller_state of a stamp counts
            b.controller(ns, names, forces=len(names), braces=len(names), desired=20.0)
        b.motor(ns, f"m{k % 40}", little)  # more layouts than MAX_PROBES of one size
        b.wrench(ns, "elbow", 10.0 + k % 4, little)
        if k % 2:
            b.wrench(ns, "wrist", 3.0, little)
        if k == 50:
            b.wrench(ns, "wrist", 2.0)  # the same stamp, a smaller force: sorted before
    b.description("<robot name='r'/>")
    b.description("<robot name='later'/>")
    return b.write(path)


def test_read_series_varying_layouts_equals_general(tmp_path: Path) -> None:
    s = assert_columnar_is_general(varying_bag(tmp_path / "bag"))
    # The bag exercised what it was built for:
    assert s.t0_ns == 1_000_000 and s.joint_names == JOINTS
    assert np.isnan(s.joint_position).sum() == 21
    assert list(s.contacts) == ["wrist", "elbow"]
    assert s.contacts["elbow"].t.size == 118 and s.contacts["wrist"].t.size == 88
    assert np.isnan(s.contacts["elbow"].normal_force_desired).sum() == 12
    assert np.isnan(s.contacts["wrist"].brace_desired).any()
    assert s.contacts["elbow"].t_matched.size == 118
    at_39ms = np.isclose(s.contacts["elbow"].t_matched, 0.038)  # two contacts messages, three controller_states
    assert s.contacts["elbow"].normal_force_error[at_39ms].tolist() == [28.0, 29.0]  # 49 N, 50 N - the last's 21 N
    assert s.contacts["wrist"].force[:, 2].tolist().count(2.0) == 1
    assert s.robot_description == "<robot name='r'/>"
    assert not np.all(s.hand_actual == s.hand_desired)


def test_read_series_without_joint_states_equals_general(tmp_path: Path) -> None:
    s = assert_columnar_is_general(varying_bag(tmp_path / "bag", with_joints=False))
    assert s.joint_t.size == 0 and s.t0_ns == 1_000_000 and s.motor_t.size == 120


def test_read_series_small_cases_equal_general(tmp_path: Path) -> None:
    only = BagBuilder()
    only.description("")
    s = assert_columnar_is_general(only.write(tmp_path / "empty_description"))
    assert s.robot_description == "" and s.t.shape == (0,) and s.hand_desired.shape == (0, 3)
    late = BagBuilder()
    late.motor(5_000_000, "m")
    late.controller(3_000_000, [], 0, 0)
    s = assert_columnar_is_general(late.write(tmp_path / "late"))
    assert s.t0_ns == 3_000_000 and s.robot_description is None and not s.contacts


def test_read_series_ragged_joint_states_fail_alike(tmp_path: Path) -> None:
    b = BagBuilder()
    b.joint(0, JOINTS)
    store = b.store
    short = store.types["sensor_msgs/msg/JointState"](b.header(1), JOINTS, np.zeros(3), np.zeros(0), np.zeros(0))
    b.add("/joint_states", "sensor_msgs/msg/JointState", short)
    bag = b.write(tmp_path / "bag")
    with pytest.raises(ValueError):
        reference_series.read_series(bag)
    with pytest.raises(ValueError):
        read_series(bag)


def test_read_series_damaged_message_is_a_bag_read_error(tmp_path: Path) -> None:
    b = BagBuilder()
    b.joint(0, JOINTS)
    b.joint(1, JOINTS)
    topic, typename, raw = b.items[1]
    b.items[1] = (topic, typename, raw[:-9])  # truncated
    bag = b.write(tmp_path / "bag")
    for read in (reference_series.read_series, read_series):
        with pytest.raises(BagReadError, match="cannot read bag"):
            read(bag)


# --------------------------------------------------------------------------- read_series on recorded bags


def test_read_series_of_pair_runs_equals_general(runs: dict[str, Path]) -> None:
    braced = assert_columnar_is_general(runs["braced"] / "bag")
    assert list(braced.contacts) == ["elbow"] and braced.contacts["elbow"].t_matched.size > 0
    assert braced.robot_description
    unbraced = assert_columnar_is_general(runs["unbraced"] / "bag")
    assert not unbraced.contacts and unbraced.joint_t.size == braced.joint_t.size


@pytest.mark.parametrize("contacts", [(), ("elbow", "wrist")], ids=["no-contacts", "two-contacts"])
def test_read_series_of_rclpy_serialized_bags_equals_general(tmp_path: Path, contacts: tuple[str, ...]) -> None:
    from test_recorder_report import write_bag_directly

    write_bag_directly(tmp_path / "bag", 60, contacts)
    s = assert_columnar_is_general(tmp_path / "bag")
    assert list(s.contacts) == list(contacts)
