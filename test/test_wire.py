"""bracing_ros.wire: the CDR bytes it builds are exactly what rclpy reads and writes.

Every encoder's bytes are decoded by rclpy (the rosidl typesupport) into the values put in,
and every decoder reads rclpy's bytes back; random values, several sizes, empty sequences.
The templates' layouts are derived from the message definitions: types changed or made up
here (extra fields of every kind) give the bytes rosbags' serialiser gives, with no code edit.
"""

from __future__ import annotations

import copy
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from bracing_core.typestore import bracing_msgs_dir, bracing_typestore
from bracing_msgs.msg import Contacts, ControllerState, MotorCommand, MotorState
from bracing_ros import cdr_template, report_encoders, wire

MOTOR_STATE = "bracing_msgs/msg/MotorState"

RNG = np.random.default_rng(7)
NAME_SETS = [[], ["j"], ["joint1", "joint2", "joint3", "joint4"], [f"link_{k}_joint" for k in range(7)], ["ß", "关节"]]


def _stamp_ns() -> int:
    return int(RNG.integers(0, 2**31 - 1)) * 1_000_000_000 + int(RNG.integers(0, 999_999_999))


def _ns(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _xyz(p: object) -> list[float]:
    return [p.x, p.y, p.z]  # type: ignore[attr-defined]


@pytest.mark.parametrize("names", NAME_SETS)
def test_joint_state_round_trips_through_rclpy(names: list[str]) -> None:
    n = len(names)
    stamp, q, dq, tau = _stamp_ns(), RNG.normal(size=n), RNG.normal(size=n), RNG.normal(size=n)
    msg = deserialize_message(wire.JointStateEncoder(names).encode(stamp, q, dq, tau), JointState)
    assert _ns(msg.header.stamp) == stamp and msg.header.frame_id == ""
    assert list(msg.name) == names
    assert list(msg.position) == q.tolist() and list(msg.velocity) == dq.tolist() and list(msg.effort) == tau.tolist()

    back = wire.decode_joint_state(serialize_message(msg))
    assert (back.stamp_ns, back.name) == (stamp, names)
    assert back.position.tolist() == q.tolist() and back.velocity.tolist() == dq.tolist()
    assert back.effort.tolist() == tau.tolist()


def test_joint_state_decoder_reads_any_layout() -> None:
    """Other publishers' JointStates: other frame ids, unequal (empty) sequences."""
    msg = JointState(name=["b", "a", "c"], position=[1.0, 2.0, 3.0], velocity=[], effort=[4.5])
    msg.header.frame_id = "base_link_frame"
    msg.header.stamp = Time(sec=12, nanosec=34)
    back = wire.decode_joint_state(serialize_message(msg))
    assert back.stamp_ns == 12_000_000_034 and back.name == ["b", "a", "c"]
    assert back.position.tolist() == [1.0, 2.0, 3.0] and back.velocity.size == 0 and back.effort.tolist() == [4.5]


def test_clock_and_wrench() -> None:
    stamp = _stamp_ns()
    clock = deserialize_message(report_encoders.ClockEncoder().encode(stamp), Clock)
    assert _ns(clock.clock) == stamp
    force = RNG.normal(size=3)
    wrench = deserialize_message(report_encoders.WrenchStampedEncoder("world").encode(stamp, force), WrenchStamped)
    assert _ns(wrench.header.stamp) == stamp and wrench.header.frame_id == "world"
    assert _xyz(wrench.wrench.force) == force.tolist() and _xyz(wrench.wrench.torque) == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("count", [0, 1, 3])
def test_contacts(count: int) -> None:
    names, frames = [f"c{k}" for k in range(count)], [f"link_{k}_frame" for k in range(count)]
    reports = [
        report_encoders.ContactReport(
            active=bool(k % 2 == 0),
            position=RNG.normal(size=3),
            normal=RNG.normal(size=3),
            normal_force=float(RNG.normal()),
            friction_force=float(RNG.normal()),
            slip_velocity=RNG.normal(size=3),
            residual=float(RNG.normal()),
        )
        for k in range(count)
    ]
    stamp = _stamp_ns()
    msg = deserialize_message(report_encoders.ContactsEncoder(names, frames).encode(stamp, reports), Contacts)
    assert _ns(msg.header.stamp) == stamp and msg.header.frame_id == "world"
    assert len(msg.contacts) == count
    for got, name, frame, want in zip(msg.contacts, names, frames, reports, strict=True):
        assert (got.name, got.frame, got.active) == (name, frame, want.active)
        assert _xyz(got.position) == want.position.tolist() and _xyz(got.normal) == want.normal.tolist()
        assert (got.normal_force, got.friction_force, got.residual) == (
            want.normal_force,
            want.friction_force,
            want.residual,
        )
        assert _xyz(got.slip_velocity) == want.slip_velocity.tolist()


@pytest.mark.parametrize("thermal", [True, False], ids=["thermal", "no-thermal"])
@pytest.mark.parametrize("names", NAME_SETS)
def test_motor_state(names: list[str], thermal: bool) -> None:
    """Both rclpy and rosbags read what the encoder writes, with the temperatures and without; and
    rosbags reads rclpy's message without them. (rclpy's CDR pads to 8 after an empty float64[]'s
    length, rosbags' does not: as the last field it would make every torque-mode MotorState
    unreadable to rosbags, hence temperature's place before the float64 integrals.)"""
    n = len(names)
    v, i, p = RNG.normal(size=n), RNG.normal(size=n), RNG.normal(size=n)
    energies = (1.5, -2.25, 3.0e-7)
    stamp = _stamp_ns()
    temperature = 25.0 + RNG.random(size=n) if thermal else np.zeros(0)
    raw = report_encoders.MotorStateEncoder(names).encode(stamp, v, i, p, energies, temperature)
    for msg in (deserialize_message(raw, MotorState), bracing_typestore().deserialize_cdr(raw, MOTOR_STATE)):
        assert list(msg.name) == names
        assert list(msg.voltage) == v.tolist() and list(msg.current) == i.tolist() and list(msg.power) == p.tolist()
        assert (msg.energy_consumed, msg.energy_net, msg.copper_loss) == energies
        assert list(msg.temperature) == temperature.tolist()
    assert _ns(deserialize_message(raw, MotorState).header.stamp) == stamp
    if not names:  # a robot without joints: rclpy's padding of four empty float64[] is not rosbags'
        return
    empty = MotorState(name=names, voltage=v.tolist(), current=i.tolist(), power=p.tolist())
    assert list(bracing_typestore().deserialize_cdr(serialize_message(empty), MOTOR_STATE).temperature) == []


@pytest.mark.parametrize("names", NAME_SETS)
@pytest.mark.parametrize("mode", [MotorCommand.VOLTAGE, MotorCommand.TORQUE])
def test_motor_command_round_trips_through_rclpy(names: list[str], mode: int) -> None:
    value, stamp = RNG.normal(size=len(names)), _stamp_ns()
    msg = deserialize_message(wire.MotorCommandEncoder(names, mode).encode(stamp, value), MotorCommand)
    assert _ns(msg.header.stamp) == stamp and msg.mode == mode
    assert list(msg.name) == names and list(msg.value) == value.tolist()

    back = wire.decode_motor_command(serialize_message(msg))
    assert (back.stamp_ns, back.mode, back.name, back.value.tolist()) == (stamp, mode, names, value.tolist())


@pytest.mark.parametrize("contacts", [[], ["elbow"], ["elbow", "wrist"]])
@pytest.mark.parametrize("n", [0, 4])
def test_controller_state(contacts: list[str], n: int) -> None:
    p = len(contacts)
    hand_desired, hand_actual = RNG.normal(size=3), RNG.normal(size=3)
    force, brace_desired, brace_actual = RNG.normal(size=p), RNG.normal(size=(p, 3)), RNG.normal(size=(p, 3))
    command, stamp = RNG.normal(size=n), _stamp_ns()
    data = wire.ControllerStateEncoder(contacts, n).encode(
        stamp, hand_desired, hand_actual, force, brace_desired, brace_actual, command, 2.5e-5
    )
    msg = deserialize_message(data, ControllerState)
    assert _ns(msg.header.stamp) == stamp and msg.header.frame_id == "world"
    assert _xyz(msg.hand_desired) == hand_desired.tolist() and _xyz(msg.hand_actual) == hand_actual.tolist()
    assert list(msg.contact_name) == contacts and list(msg.desired_normal_force) == force.tolist()
    assert [_xyz(b) for b in msg.brace_desired] == brace_desired.tolist()
    assert [_xyz(b) for b in msg.brace_actual] == brace_actual.tolist()
    assert list(msg.command) == command.tolist() and msg.compute_time == 2.5e-5


def test_big_endian_cdr_is_read() -> None:
    # A MotorCommand written big-endian by hand: stamp 5 s 6 ns, frame "", mode 1, ["a"], [2.0].
    data = (
        b"\x00\x00\x00\x00"
        + (5).to_bytes(4, "big")
        + (6).to_bytes(4, "big")
        + (1).to_bytes(4, "big")
        + b"\x00"
        + b"\x01"
        + b"\x00\x00"
        + (1).to_bytes(4, "big")
        + (2).to_bytes(4, "big")
        + b"a\x00"
        + b"\x00\x00"
        + (1).to_bytes(4, "big")
        + np.array([2.0], dtype=">f8").tobytes()
    )
    back = wire.decode_motor_command(data)
    assert (back.stamp_ns, back.mode, back.name, back.value.tolist()) == (5_000_000_006, 1, ["a"], [2.0])


def test_bad_bytes_raise_decode_errors() -> None:
    # (rclpy's own bytes end with a few unused bytes; these end where the content does.)
    good = wire.JointStateEncoder(["a", "b"]).encode(5, np.ones(2), np.ones(2), np.ones(2))
    for cut in range(4, len(good)):
        with pytest.raises(wire.DecodeError):
            wire.decode_joint_state(good[:cut])
    with pytest.raises(wire.UnsupportedEncoding):
        wire.decode_joint_state(b"\x00\x07\x00\x00" + good[4:])  # XCDR2
    with pytest.raises(wire.UnsupportedEncoding):
        wire.decode_motor_command(b"")
    huge = bytearray(good)
    huge[12:16] = (2**31).to_bytes(4, "little")  # frame_id length far past the end
    with pytest.raises(wire.DecodeError):
        wire.decode_joint_state(bytes(huge))


def test_layout_decoders_agree_with_the_general_ones() -> None:
    """The decoders' quick path (the expected layout) and their general path read the same values."""
    names = ["joint1", "joint2", "joint3", "joint4"]
    states = wire.JointStateDecoder(names)
    commands = wire.MotorCommandDecoder(names, MotorCommand.VOLTAGE)
    q, dq, tau = RNG.normal(size=4), RNG.normal(size=4), RNG.normal(size=4)
    same_layout = JointState(name=names, position=q.tolist(), velocity=dq.tolist(), effort=tau.tolist())
    other_layout = JointState(name=names[::-1], position=q.tolist(), velocity=dq.tolist(), effort=[])
    other_layout.header.frame_id = "base"
    for msg in (same_layout, other_layout):
        msg.header.stamp = Time(sec=3, nanosec=4)
        data = serialize_message(msg)  # with rclpy's extra bytes at the end
        quick, general = states.decode(data), wire.decode_joint_state(data)
        assert (quick.stamp_ns, quick.name) == (general.stamp_ns, general.name) == (3_000_000_004, list(msg.name))
        for a, b in ((quick.position, general.position), (quick.velocity, general.velocity)):
            assert a.tolist() == b.tolist()
        assert quick.effort.tolist() == general.effort.tolist() == list(msg.effort)
    for mode, order in ((MotorCommand.VOLTAGE, names), (MotorCommand.TORQUE, names), (MotorCommand.VOLTAGE, names[:3])):
        command = MotorCommand(mode=mode, name=order, value=RNG.normal(size=len(order)).tolist())
        data = serialize_message(command)
        quick, general = commands.decode(data), wire.decode_motor_command(data)
        assert (quick.mode, quick.name, quick.value.tolist()) == (general.mode, general.name, general.value.tolist())
        assert (quick.mode, quick.name, quick.value.tolist()) == (mode, order, list(command.value))


# ------------------------------------------------------------------ layouts from definitions


def test_typestore_is_built_once_and_shared_with_the_recorder() -> None:
    from bracing_recorder import command

    store = bracing_typestore()
    assert store is bracing_typestore() is command.bracing_typestore()
    assert "bracing_msgs/msg/MotorCommand" in store.fielddefs and "sensor_msgs/msg/JointState" in store.fielddefs


# A MotorCommand grown by fields of every kind, one in the middle (after the uint8 mode: alignment).
GROWN_MOTOR_COMMAND = """uint8 VOLTAGE=0
uint8 TORQUE=1
std_msgs/Header header
uint8 mode
float64 gain
string[] name
float64[] value
int16[3] limit
geometry_msgs/Point[] target
string note
bool enabled
"""


@pytest.fixture
def grown_store(tmp_path: Path) -> Typestore:
    """The bracing typestore with MotorCommand.msg edited (a copy of the msg directory)."""
    for path in bracing_msgs_dir().glob("*.msg"):
        shutil.copy(path, tmp_path / path.name)
    (tmp_path / "MotorCommand.msg").write_text(GROWN_MOTOR_COMMAND, encoding="utf-8")
    return bracing_typestore(tmp_path)


def test_a_field_added_to_the_msg_needs_no_code(grown_store: Typestore, monkeypatch: pytest.MonkeyPatch) -> None:
    """The MotorCommand encoder and decoders on the grown definition: new fields at their defaults."""
    for module in (wire, cdr_template):  # the decoders' reader and the templates' layout
        monkeypatch.setattr(module, "bracing_typestore", lambda: grown_store)
    names, value, stamp = ["a", "bb", "ccc"], RNG.normal(size=3), _stamp_ns()
    data = wire.MotorCommandEncoder(names, MotorCommand.TORQUE).encode(stamp, value)

    types = grown_store.types
    expected = types["bracing_msgs/msg/MotorCommand"](
        header=types["std_msgs/msg/Header"](types["builtin_interfaces/msg/Time"](*divmod(stamp, 10**9)), ""),
        mode=MotorCommand.TORQUE,
        gain=0.0,
        name=names,
        value=value,
        limit=np.zeros(3, dtype=np.int16),
        target=[],
        note="",
        enabled=False,
    )
    assert data == bytes(grown_store.serialize_cdr(expected, "bracing_msgs/msg/MotorCommand", little_endian=True))
    decoder = wire.MotorCommandDecoder(names, MotorCommand.TORQUE)
    assert decoder._template.read(data) is not None  # the quick path
    for back in (decoder.decode(data), wire.decode_motor_command(data)):
        assert (back.stamp_ns, back.mode, back.name, back.value.tolist()) == (stamp, 1, names, value.tolist())


def test_a_grown_joint_state_needs_no_code(monkeypatch: pytest.MonkeyPatch) -> None:
    """A JointState-like type with extra fields, in a typestore of its own."""
    store = Typestore()
    definitions = {
        "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec",
        "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id",
        "sensor_msgs/msg/JointState": (
            "std_msgs/Header header\nuint8 flags\nstring[] name\nfloat64[] position\nfloat32 scale\n"
            "float64[] velocity\nfloat64[] effort\nfloat64[] temperature\nint64 counter"
        ),
    }
    for typename, text in definitions.items():
        store.register(get_types_from_msg(text, typename))
    for module in (wire, cdr_template):  # the decoders' reader and the templates' layout
        monkeypatch.setattr(module, "bracing_typestore", lambda: store)
    names, stamp = ["j1", "j2"], _stamp_ns()
    q, dq, tau = RNG.normal(size=2), RNG.normal(size=2), RNG.normal(size=2)
    data = wire.JointStateEncoder(names).encode(stamp, q, dq, tau)
    types = store.types
    expected = types["sensor_msgs/msg/JointState"](
        types["std_msgs/msg/Header"](types["builtin_interfaces/msg/Time"](*divmod(stamp, 10**9)), ""),
        0,
        names,
        q,
        0.0,
        dq,
        tau,
        np.zeros(0),
        0,
    )
    assert data == bytes(store.serialize_cdr(expected, "sensor_msgs/msg/JointState", little_endian=True))
    decoder = wire.JointStateDecoder(names)
    assert decoder._template.read(data) is not None  # the quick path
    for back in (decoder.decode(data), wire.decode_joint_state(data)):
        assert (back.stamp_ns, back.name) == (stamp, names)
        assert (back.position.tolist(), back.velocity.tolist(), back.effort.tolist()) == (
            q.tolist(),
            dq.tolist(),
            tau.tolist(),
        )


# Every kind of field the template builder walks: scalars of each size, strings, fixed arrays,
# sequences of numbers, strings and messages, nested messages, in an order that needs padding.
SAMPLE = """uint8 FLAG=1
bool on
int8 small
std_msgs/Header header
uint16 medium
float64 x
string<=10 label
int32[3] triple
geometry_msgs/Point point
float32 ratio
string[] tags
float64[] values
geometry_msgs/Point[] points
int64 big
uint8[] raw
test_msgs/Inner[2] pair
test_msgs/Inner[] inners
uint32 last
"""
INNER = "string name\nbool active\ngeometry_msgs/Vector3 v\nfloat64 w\nuint8 tail"


@pytest.fixture(scope="module")
def sample_store() -> Typestore:
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(INNER, "test_msgs/msg/Inner"))
    store.register(get_types_from_msg(SAMPLE, "test_msgs/msg/Sample"))
    return store


def _random_message(store: Typestore, typename: str, count: int) -> Any:
    """A message of ``typename`` with random values and ``count`` elements in each sequence."""
    values = []
    for _, desc in store.get_msgdef(typename).fields:
        values.append(_random_value(store, desc, count))
    return store.types[typename](*values)


def _random_value(store: Typestore, desc: Any, count: int) -> Any:
    kind, arg = desc
    if kind == Nodetype.NAME:
        return _random_message(store, arg, count)
    if kind == Nodetype.BASE:
        return _random_scalar(arg[0])
    sub, length = arg
    length = length if kind == Nodetype.ARRAY else count
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        dtype = {"bool": np.bool_}.get(sub[1][0], sub[1][0])
        return np.array([_random_scalar(sub[1][0]) for _ in range(length)], dtype=dtype)
    return [_random_value(store, sub, count) for _ in range(length)]


def _random_scalar(base: str) -> Any:
    if base == "string":
        return "".join(RNG.choice(list("abcßλ")) for _ in range(int(RNG.integers(0, 6))))
    if base == "bool":
        return bool(RNG.integers(0, 2))
    if base.startswith("float"):
        return float(np.float32(RNG.normal())) if base == "float32" else float(RNG.normal())
    info = np.iinfo(base)
    return int(RNG.integers(info.min, info.max, endpoint=True))


def _spec(store: Typestore, typename: str, message: Any, live: set[str], path: str = "") -> tuple[dict, list]:
    """The template spec of ``message`` with the fields named in ``live`` per message, and their values."""
    spec: dict[str, Any] = {}
    values: list[list[Any]] = []
    fields: list[tuple[str, Any]] = store.get_msgdef(typename).fields
    for name, (kind, arg) in fields:
        value, where = getattr(message, name), path + name
        if where in live:
            spec[name] = cdr_template.PerMessage(len(value)) if kind == Nodetype.SEQUENCE else cdr_template.PER_MESSAGE
            values.append(_numbers(value))
        elif kind == Nodetype.NAME:
            spec[name], inner = _spec(store, arg, value, live, where + ".")
            values += inner
        elif kind != Nodetype.BASE and arg[0][0] == Nodetype.NAME:
            spec[name] = []
            for k, element in enumerate(value):
                element_spec, inner = _spec(store, arg[0][1], element, live, f"{where}[{k}].")
                spec[name].append(element_spec)
                values += inner
        else:
            spec[name] = value.tolist() if isinstance(value, np.ndarray) else value
    return spec, values


def _numbers(value: Any) -> list[Any]:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [x for element in value for x in _numbers(element)]
    if hasattr(value, "__dataclass_fields__"):
        return [
            x for name in value.__dataclass_fields__ if name != "__msgtype__" for x in _numbers(getattr(value, name))
        ]
    return [value]


LIVE_SETS = [
    set(),
    {"header.stamp", "x", "values"},
    {"on", "small", "medium", "x", "triple", "point", "ratio", "values", "points", "big", "raw", "last"},
    {"header.stamp", "pair[0].v", "pair[1].active", "pair[1].w", "inners[0].tail", "inners[2].v", "last"},
]


@pytest.mark.parametrize("count", [0, 1, 3])
@pytest.mark.parametrize("live", LIVE_SETS, ids=lambda s: ",".join(sorted(s)) or "constant")
def test_derived_templates_agree_with_rosbags(sample_store: Typestore, count: int, live: set[str]) -> None:
    """Constants from one random message, per-message numbers from others: rosbags' bytes each time."""
    typename = "test_msgs/msg/Sample"
    constant = _random_message(sample_store, typename, count)
    spec, _ = _spec(sample_store, typename, constant, live)
    template = cdr_template.derive_template(typename, spec, sample_store)
    for _ in range(3):
        expected = _merge(sample_store, typename, constant, _random_message(sample_store, typename, count), live)
        _, values = _spec(sample_store, typename, expected, live)
        data = template.fill(*values)
        assert data == bytes(sample_store.serialize_cdr(expected, typename, little_endian=True))
        assert template.read(data + b"\x07" * 5) == [tuple(v) for v in values]  # trailing bytes ignored
        assert template.read(data[:-1]) is None
        other = copy.deepcopy(expected)  # another frame id: another layout
        other.header.frame_id = "z" * max(1, len(other.header.frame_id.encode()))
        assert template.read(bytes(sample_store.serialize_cdr(other, typename, little_endian=True))) is None


def _merge(store: Typestore, typename: str, constant: Any, fresh: Any, live: set[str], path: str = "") -> Any:
    """``constant`` with the fields named in ``live`` taken from ``fresh``."""
    values = []
    fields: list[tuple[str, Any]] = store.get_msgdef(typename).fields
    for name, (kind, arg) in fields:
        where = path + name
        if where in live:
            values.append(getattr(fresh, name))
        elif kind == Nodetype.NAME:
            values.append(_merge(store, arg, getattr(constant, name), getattr(fresh, name), live, where + "."))
        elif kind != Nodetype.BASE and arg[0][0] == Nodetype.NAME:
            pairs = enumerate(zip(getattr(constant, name), getattr(fresh, name), strict=True))
            values.append([_merge(store, arg[0][1], c, f, live, f"{where}[{k}].") for k, (c, f) in pairs])
        else:
            values.append(getattr(constant, name))
    return store.types[typename](*values)


def test_template_specs_are_checked(sample_store: Typestore) -> None:
    typename = "test_msgs/msg/Sample"
    cases: list[tuple[str, dict[str, Any], str]] = [
        (typename, {"nope": 1}, "no field nope"),
        (typename, {"header": cdr_template.PER_MESSAGE}, "string"),  # header.frame_id
        (typename, {"pair": cdr_template.PER_MESSAGE}, "string"),  # Inner.name
        (typename, {"values": cdr_template.PER_MESSAGE}, "needs its length"),
        (typename, {"x": cdr_template.PerMessage(2)}, "only a sequence"),
        (typename, {"triple": [1, 2]}, "array of 3"),
        (typename, {"label": "x" * 11}, "at most 10 characters"),
        ("geometry_msgs/msg/PolygonStamped", {"polygon": cdr_template.PER_MESSAGE}, "sequence inside"),
    ]
    for name, spec, match in cases:
        with pytest.raises(ValueError, match=match):
            cdr_template.derive_template(name, spec, sample_store)
    with pytest.raises(TypeError):
        cdr_template.derive_template(typename, {"label": 5}, sample_store)


def test_odometry_template_is_rclpys_message_byte_for_byte() -> None:
    """The odom template equals the message rclpy serialises, every field set as the simulator sets it."""
    stamp, yaw = 12_345_678_901, 0.7
    quaternion = (0.0, 0.0, float(np.sin(0.5 * yaw)), float(np.cos(0.5 * yaw)))
    raw = wire.OdometryEncoder("odom", "base_footprint").encode(stamp, (1.25, -0.5), quaternion, (0.3, -0.01), 0.2)
    msg = Odometry()
    msg.header.stamp = Time(sec=12, nanosec=345_678_901)
    msg.header.frame_id, msg.child_frame_id = "odom", "base_footprint"
    msg.pose.pose.position.x, msg.pose.pose.position.y = 1.25, -0.5
    orientation = msg.pose.pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = quaternion
    twist = msg.twist.twist
    twist.linear.x, twist.linear.y, twist.angular.z = 0.3, -0.01, 0.2
    assert raw == serialize_message(msg)
