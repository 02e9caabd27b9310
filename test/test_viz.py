"""Seeing the robot: robot_description, /tf and contact_markers in the bag, the animation, the comparison.

Two short real bracing-pair runs (braced and unbraced, 0.3 s each) are recorded once per
module; their bags are read with rosbags using only the definitions embedded in them.
"""

from __future__ import annotations

import dataclasses
import json
import math
import select
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import SHORT_RUN_S
from ros_helpers import PAPER_YAML, isolated_env, node_argv, start
from rosbags.highlevel import AnyReader

import bracing_recorder.scene as scene_module
from bracing_analysis.animation import (
    FORCE_COLOR,
    LINK_COLOR,
    POINT_COLOR,
    SURFACE_COLOR,
    TARGET_COLOR,
    TRAIL_COLOR,
    ArmAnimation,
    GifWriter,
    Palette,
    frame_times,
)
from bracing_analysis.bag import read_series
from bracing_analysis.compare import write_comparison
from bracing_analysis.report import main as report_main
from bracing_analysis.report import write_report
from bracing_core.kinematics import DescriptionError
from bracing_core.typestore import bracing_typestore
from bracing_recorder.recorder import missing_messages
from bracing_recorder.scene import FORCE_ARROW_M_PER_N, SceneBuilder
from bracing_ros import wire

DURATION = SHORT_RUN_S  # the `runs` fixture's (conftest)
STATES = 301  # 0.3 s at 1 ms, both ends
PAPER_URDF = PAPER_YAML.parent / "paper_4link.urdf"
Q0 = np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi  # the paper's start pose
ELBOW0 = np.array([0.0, 0.5878, 0.0])  # where that pose puts the elbow and the hand
HAND0 = np.array([0.0, 1.0633, 0.6545])


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def read_bag(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """topic -> [(bag time, message)], in bag-time order, decoded with the bag's own definitions."""
    out: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([bag]) as reader:
        for connection in reader.connections:
            out.setdefault(connection.topic, [])
        for connection, stamp, raw in reader.messages():
            out[connection.topic].append((stamp, reader.deserialize(raw, connection.msgtype)))
    return out


@pytest.fixture(scope="module")
def braced(runs: dict[str, Path]) -> dict[str, list[tuple[int, Any]]]:
    return read_bag(runs["braced"] / "bag")


# --------------------------------------------------------------------------- the bag


def test_robot_description_is_the_urdf_the_simulator_loaded(braced: dict[str, list[tuple[int, Any]]]) -> None:
    (_, description), *rest = braced["/robot_description"]
    assert not rest
    assert description.data == PAPER_URDF.read_text(encoding="utf-8")


def test_tf_equals_pinocchio_kinematics_of_every_recorded_state(braced: dict[str, list[tuple[int, Any]]]) -> None:
    model = pin.buildModelFromXML(braced["/robot_description"][0][1].data)
    data = model.createData()
    links = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
    states = {_ns(m.header.stamp): m for _, m in braced["/joint_states"]}
    tfs = braced["/tf"]
    assert len(states) == STATES
    # One /tf per state, stamped (header and bag time) like its joint_states.
    assert sorted(stamp for stamp, _ in tfs) == sorted(states)
    (_, static), *more_static = braced["/tf_static"]
    assert not more_static
    parents = {t.child_frame_id: t.header.frame_id for t in static.transforms}
    assert parents == {"base_link": "world"}  # the root link never moves
    assert static.transforms[0].transform.translation.z == 0.0
    for stamp, message in tfs:
        state = states[stamp]
        q = np.zeros(model.nq)
        for name, value in zip(state.name, state.position, strict=True):
            q[model.joints[model.getJointId(name)].idx_q] = value
        pin.framesForwardKinematics(model, data, q)
        seen = set()
        for tf in message.transforms:
            assert _ns(tf.header.stamp) == stamp and tf.header.frame_id == "world"
            expected = data.oMf[model.getFrameId(tf.child_frame_id)]
            p, r = tf.transform.translation, tf.transform.rotation
            assert np.allclose([p.x, p.y, p.z], expected.translation, rtol=0.0, atol=1e-9)
            rotation = pin.Quaternion(r.w, r.x, r.y, r.z).toRotationMatrix()
            assert np.allclose(rotation, expected.rotation, rtol=0.0, atol=1e-9)
            seen.add(tf.child_frame_id)
            parents[tf.child_frame_id] = tf.header.frame_id
        assert seen == links - {"base_link"}
    # The tree: every link of the URDF hangs from world, each with one parent.
    assert set(parents) == links and set(parents.values()) == {"world"}


def test_tf_puts_the_elbow_where_the_simulator_holds_it(braced: dict[str, list[tuple[int, Any]]]) -> None:
    """Two kinematics agree: the recorder's TF (from joint_states) and the simulator's contact point."""
    contact = {stamp: m.contacts[0].position for stamp, m in braced["/contacts"]}
    first_stamp = min(stamp for stamp, _ in braced["/tf"])
    for stamp, message in braced["/tf"]:
        poses = {t.child_frame_id: t.transform.translation for t in message.transforms}
        elbow, c = poses["elbow"], contact[stamp]
        assert [elbow.x, elbow.y, elbow.z] == pytest.approx([c.x, c.y, c.z], abs=1e-9)
        assert abs(elbow.z) < 1e-9  # bilateral contact with the floor z = 0
        if stamp == first_stamp:
            hand = poses["hand"]
            assert [elbow.x, elbow.y, elbow.z] == pytest.approx(ELBOW0, abs=1e-4)
            assert [hand.x, hand.y, hand.z] == pytest.approx(HAND0, abs=1e-4)


def test_marker_arrows_are_the_contact_wrenches(braced: dict[str, list[tuple[int, Any]]]) -> None:
    wrench = {_ns(m.header.stamp): m.wrench.force for _, m in braced["/contact_wrench/elbow"]}
    contacts = {_ns(m.header.stamp): m.contacts[0] for _, m in braced["/contacts"]}
    markers = braced["/contact_markers"]
    assert sorted(stamp for stamp, _ in markers) == sorted(wrench)
    types = {0: "ARROW", 1: "CUBE", 2: "SPHERE"}
    largest = 0.0
    for stamp, message in markers:
        by_type = {types[m.type]: m for m in message.markers}
        assert set(by_type) == {"ARROW", "CUBE", "SPHERE"}
        assert {m.ns for m in message.markers} == {"elbow"}
        assert all(m.header.frame_id == "world" and _ns(m.header.stamp) == stamp for m in message.markers)
        f, c = wrench[stamp], contacts[stamp]
        start, end = by_type["ARROW"].points
        drawn = (np.array([end.x, end.y, end.z]) - [start.x, start.y, start.z]) / FORCE_ARROW_M_PER_N
        assert drawn == pytest.approx([f.x, f.y, f.z], rel=1e-12, abs=1e-9)
        assert [start.x, start.y, start.z] == [c.position.x, c.position.y, c.position.z]
        sphere = by_type["SPHERE"].pose.position
        assert [sphere.x, sphere.y, sphere.z] == [c.position.x, c.position.y, c.position.z]
        # The surface patch lies in the floor, its thin axis along the normal (+z).
        surface = by_type["CUBE"].pose
        assert surface.position.z == pytest.approx(0.0, abs=1e-12)
        o = surface.orientation
        axis = pin.Quaternion(o.w, o.x, o.y, o.z).toRotationMatrix()[:, 2]
        assert axis == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
        largest = max(largest, math.hypot(f.x, f.y, f.z))
    assert largest > 5.0  # the elbow is pressed on the floor (f_nd = 10 N): the arrows have length


def test_completeness_check_counts_the_derived_topics(runs: dict[str, Path]) -> None:
    bag = runs["braced"] / "bag"
    assert missing_messages(bag, ["elbow"], STATES) == []
    short = missing_messages(bag, ["elbow"], STATES + 1)
    assert f"/tf: {STATES} of {STATES + 1} messages" in short
    assert f"/contact_markers: {STATES} of {STATES + 1} messages" in short
    assert not any(line.startswith(("/tf_static", "/robot_description")) for line in short)


def test_unbraced_bag_has_tf_and_no_markers(runs: dict[str, Path]) -> None:
    data = read_bag(runs["unbraced"] / "bag")
    assert len(data["/tf"]) == STATES and len(data["/tf_static"]) == 1
    assert "/contact_markers" not in data
    assert missing_messages(runs["unbraced"] / "bag", [], STATES) == []


LATE_SUBSCRIBER = """
import hashlib, sys, time
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("late_viewer")
got = []
qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
node.create_subscription(String, "robot_description", lambda m: got.append(m.data), qos)
deadline = time.monotonic() + 20.0
while not got and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
print(hashlib.sha256(got[0].encode()).hexdigest() if got else "nothing", flush=True)
"""


def test_simulator_latches_robot_description_for_late_viewers() -> None:
    """RViz or robot_state_publisher started after the simulator still get the URDF (transient-local)."""
    import hashlib

    env = isolated_env()
    sim = start(node_argv("bracing_sim.node"), env)  # lockstep: it waits for a controller, publishing nothing else
    try:
        assert sim.stdout is not None
        ready, deadline = False, time.monotonic() + 30.0
        while not ready and time.monotonic() < deadline:
            if select.select([sim.stdout], [], [], 0.5)[0]:
                ready = "input," in sim.stdout.readline()  # the start-up line: the URDF is published
        assert ready, "the simulator did not start"
        time.sleep(1.0)  # join well after the publish
        viewer = subprocess.run(
            [sys.executable, "-c", LATE_SUBSCRIBER], env=env, capture_output=True, text=True, timeout=60
        )
    finally:
        sim.terminate()
        sim.communicate(timeout=20)
    assert viewer.stdout.strip() == hashlib.sha256(PAPER_URDF.read_bytes()).hexdigest(), viewer.stderr


# --------------------------------------------------------------------------- the scene builder, without DDS


def test_scene_waits_for_the_description_and_for_every_wrench(runs: dict[str, Path]) -> None:
    """States recorded before robot_description get their /tf once it arrives; markers need all parts."""
    from rosbags.rosbag2 import Reader

    raw: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(runs["braced"] / "bag") as reader:
        for connection, stamp, data in reader.messages():
            raw.setdefault(connection.topic, []).append((stamp, bytes(data)))
    scene = SceneBuilder(bracing_typestore(), ["elbow"])
    early = [scene.joint_state(stamp, data) for stamp, data in raw["/joint_states"][:3]]
    assert early == [[], [], []] and scene.waiting == 3
    out = scene.description(raw["/robot_description"][0][1])
    assert [d.key for d in out] == ["tf_static", "tf", "tf", "tf"]
    assert [d.stamp_ns for d in out[1:]] == [stamp for stamp, _ in raw["/joint_states"][:3]]
    assert [bytes(d.data) for d in out[1:]] == [data for _, data in raw["/tf"][:3]]  # what the recorder wrote
    stamp, contacts = raw["/contacts"][0]
    assert scene.contacts(stamp, contacts) == []  # its wrench is still missing
    wrench = dict(raw["/contact_wrench/elbow"])[stamp]
    (markers,) = scene.wrench("elbow", stamp, wrench)
    assert markers.key == "contact_markers" and markers.stamp_ns == stamp
    assert bytes(markers.data) == dict(raw["/contact_markers"])[stamp]
    assert scene.waiting == 0
    with pytest.raises(DescriptionError):
        SceneBuilder(bracing_typestore()).description(
            bytes(bracing_typestore().serialize_cdr(_string("<robot name='x'><joint/></robot>"), "std_msgs/msg/String"))
        )


def _string(text: str) -> Any:
    return bracing_typestore().types["std_msgs/msg/String"](data=text)


SCENE_TYPES = {  # derived topic key -> message type
    "tf": "tf2_msgs/msg/TFMessage",
    "tf_static": "tf2_msgs/msg/TFMessage",
    "contact_markers": "visualization_msgs/msg/MarkerArray",
}


def _raw_inputs(bag: Path) -> list[tuple[str, bytes]]:
    """The scene's inputs recorded in a bag, (topic, CDR bytes) in bag order."""
    from rosbags.rosbag2 import Reader

    topics = ("/joint_states", "/contacts", "/robot_description")
    with Reader(bag) as reader:
        return [
            (connection.topic, bytes(data))
            for connection, _, data in reader.messages()
            if connection.topic in topics or connection.topic.startswith("/contact_wrench/")
        ]


def _derive(inputs: list[tuple[str, bytes]], contacts: list[str]) -> tuple[SceneBuilder, list[tuple[str, int, bytes]]]:
    """Every message a SceneBuilder derives from ``inputs``, fed as the recorder feeds it (header stamps)."""
    scene = SceneBuilder(bracing_typestore(), contacts)
    out = []
    for topic, data in inputs:
        sec, nanosec = struct.unpack_from("<iI", data, 4)  # header.stamp, after the encapsulation header
        stamp = sec * 1_000_000_000 + nanosec
        if topic == "/robot_description":
            derived = scene.description(data)
        elif topic == "/joint_states":
            derived = scene.joint_state(stamp, data)
        elif topic == "/contacts":
            derived = scene.contacts(stamp, data)
        else:
            derived = scene.wrench(topic.removeprefix("/contact_wrench/"), stamp, data)
        out += [(d.key, d.stamp_ns, bytes(d.data)) for d in derived]
    return scene, out


def _derive_general(inputs: list[tuple[str, bytes]], contacts: list[str]) -> list[tuple[str, int, bytes]]:
    """``_derive`` with no byte template: rosbags' deserialiser and serialiser for every message."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(scene_module._Layout, "fast", lambda self, key, values: None)
        patch.setattr(scene_module._Reader, "read", lambda self, data: None)
        patch.setattr(wire.JointStateDecoder, "decode", lambda self, data: wire.decode_joint_state(data))
        scene, out = _derive(inputs, contacts)
    assert scene.general["tf"] == STATES  # no template was used
    return out


@pytest.mark.parametrize("name", ["braced", "unbraced"])
def test_scene_templates_give_rosbags_bytes_for_every_message(runs: dict[str, Path], name: str) -> None:
    """The byte templates' messages are, byte for byte, rosbags' serialisation of the same messages."""
    inputs = _raw_inputs(runs[name] / "bag")
    contacts = sorted({topic.removeprefix("/contact_wrench/") for topic, _ in inputs if "wrench" in topic})
    scene, out = _derive(inputs, contacts)
    general = _derive_general(inputs, contacts)
    assert len(out) == len(general) == (2 * STATES + 1 if contacts else STATES + 1)
    for mine, theirs in zip(out, general, strict=True):
        assert mine == theirs
    # The templates did the work: rosbags only for the first message of each kind.
    kinds = ["tf", "contacts", *(["wrench", "contact_markers"] if contacts else [])]  # unbraced: no contact
    assert scene.general == dict.fromkeys(kinds, 1)
    # What the recorder wrote, and rosbags' own bytes for what they hold.
    from rosbags.rosbag2 import Reader

    with Reader(runs[name] / "bag") as reader:
        written = [
            (connection.topic, stamp, bytes(data))
            for connection, stamp, data in reader.messages()
            if connection.topic in ("/tf", "/tf_static", "/contact_markers")
        ]
    assert sorted(written) == sorted((f"/{key}", stamp, data) for key, stamp, data in out)
    store = bracing_typestore()
    for key, _, data in out:
        assert bytes(store.serialize_cdr(store.deserialize_cdr(data, SCENE_TYPES[key]), SCENE_TYPES[key])) == data


@pytest.mark.parametrize("at", ["first", "middle"])
def test_scene_falls_back_to_rosbags_when_the_layout_changes(runs: dict[str, Path], at: str) -> None:
    """Messages of another layout than the first (contacts, names, frame ids) take rosbags' path, same bytes."""
    store = bracing_typestore()
    inputs = _raw_inputs(runs["braced"] / "bag")
    where = {topic: [k for k, (t, _) in enumerate(inputs) if t == topic] for topic in dict(inputs)}
    pick = 0 if at == "first" else len(where["/contacts"]) // 2

    def edit(topic: str, offset: int, typename: str, change: Any) -> None:
        k = where[topic][pick + offset]
        message = store.deserialize_cdr(inputs[k][1], typename)
        change(message)
        inputs[k] = (topic, bytes(store.serialize_cdr(message, typename)))

    def two_contacts(m: Any) -> None:  # a second contact, released
        m.contacts = [m.contacts[0], dataclasses.replace(m.contacts[0], name="knee", frame="link3", active=False)]

    def renamed(m: Any) -> None:  # the same length of name: only the bytes of the name differ
        m.contacts = [dataclasses.replace(m.contacts[0], name="wrist")]

    def released(m: Any) -> None:  # the same layout, another color
        m.contacts = [dataclasses.replace(m.contacts[0], active=False)]

    def other_frame(m: Any) -> None:
        m.header.frame_id = "link2"

    def reordered(m: Any) -> None:
        m.name, m.position = m.name[::-1], m.position[::-1].copy()

    edit("/contacts", 0, "bracing_msgs/msg/Contacts", two_contacts)
    edit("/contacts", 1, "bracing_msgs/msg/Contacts", renamed)
    edit("/contacts", 2, "bracing_msgs/msg/Contacts", released)
    edit("/contact_wrench/elbow", 3, "geometry_msgs/msg/WrenchStamped", other_frame)
    edit("/joint_states", 4, "sensor_msgs/msg/JointState", other_frame)
    edit("/joint_states", 5, "sensor_msgs/msg/JointState", reordered)
    scene, out = _derive(inputs, ["elbow"])
    assert out == _derive_general(inputs, ["elbow"])
    assert len(out) == 2 * STATES + 1 and scene.waiting == 0
    markers = [
        store.deserialize_cdr(data, SCENE_TYPES[key]).markers for key, _, data in out if key == "contact_markers"
    ]
    assert [len(m) for m in markers[pick : pick + 3]] == [5, 2, 3]  # knee: no wrench, no arrow; wrist: no arrow
    assert {m.ns for m in markers[pick + 1]} == {"wrist"}
    # rosbags for the first message of each kind (it makes the template) and the odd ones; templates for the rest.
    if at == "first":  # the templates have the odd first layout: rosbags for every contacts and markers message
        assert scene.general == {"tf": 1, "contacts": STATES, "contact_markers": STATES, "wrench": 1 + 1}
    else:
        assert scene.general == {"tf": 1, "contacts": 1 + 2, "contact_markers": 1 + 2, "wrench": 1 + 1}


# --------------------------------------------------------------------------- the animation


def _close(pixel: np.ndarray, color: str, tolerance: float = 60.0) -> bool:
    rgb = np.array([int(color[i : i + 2], 16) for i in (1, 3, 5)], dtype=float)
    return float(np.linalg.norm(pixel.astype(float) - rgb)) < tolerance


def test_animation_frames_and_start_pose(runs: dict[str, Path], tmp_path: Path) -> None:
    from PIL import Image

    out = tmp_path / "report"
    write_report(runs["braced"] / "bag", out, animation_interval_s=0.1)
    gif = Image.open(out / "animation.gif")
    assert getattr(gif, "n_frames", 1) == 4  # t = 0, 0.1, 0.2, 0.3 s
    assert gif.size == (640, 480)
    gif.seek(0)
    first = np.asarray(gif.convert("RGB"))
    animation = ArmAnimation(read_series(runs["braced"] / "bag"), 0.1)
    assert animation.axes == (1, 2)  # the paper's arm moves in y-z
    # The links of the paper's start pose: shoulder (0, 0) -> knee -> elbow (0.5878, 0) -> ... -> hand.
    knee = np.array([0.0, 0.5 * math.sin(0.2 * math.pi), 0.5 * math.cos(0.2 * math.pi)])
    wrist = ELBOW0 + np.array([0.0, 0.0, 0.5])
    for a, b in ((np.zeros(3), knee), (knee, ELBOW0), (wrist, HAND0)):
        col, row = animation.pixel((a + b) / 2)
        assert _close(first[row, col], LINK_COLOR), (a, b, first[row, col])
    for empty in ([0.0, 0.0, 0.25], [0.0, 0.3, 0.15], [0.0, 0.9, 0.3]):  # where another pose would have links
        col, row = animation.pixel(empty)
        assert _close(first[row, col], "#ffffff"), (empty, first[row, col])
    # The force arrow starts at the elbow and points up (the floor pushes; tilted by the friction, mu f_n
    # at the start, where Coulomb friction breaks the elbow away): orange along it just off the elbow.
    force = animation.contacts[0].force[0]
    assert force[2] > 5.0 * abs(force[1])
    col, row = animation.pixel(ELBOW0 + 0.06 * force / np.linalg.norm(force))
    assert _close(first[row, col], "#ff8c00"), first[row, col]
    # The last frame has moved on.
    gif.seek(3)
    assert not np.array_equal(np.asarray(gif.convert("RGB")), first)
    mp4 = out / "animation.mp4"
    if mp4.exists():  # imageio-ffmpeg is pinned, so it is there in the venv
        import imageio_ffmpeg

        assert imageio_ffmpeg.count_frames_and_secs(str(mp4))[0] == 4
        # ffmpeg reads the palette indices and the palette: the links keep their colour.
        frames = imageio_ffmpeg.read_frames(str(mp4))
        size = next(frames)["size"]
        video = np.frombuffer(next(frames), dtype=np.uint8).reshape(size[1], size[0], 3)
        frames.close()
        col, row = animation.pixel(knee / 2)
        assert _close(video[row, col], LINK_COLOR), video[row, col]


def test_frame_count_follows_the_interval() -> None:
    assert frame_times(10.0, 0.1).size == 101
    assert frame_times(0.3, 0.1).size == 4
    assert frame_times(0.3, 0.07).size == 5
    assert frame_times(0.0, 0.1).size == 1


def test_palette_keeps_the_drawing_colours_and_the_gif_its_frames(tmp_path: Path) -> None:
    """White, black and every drawing colour are reduced to themselves; the GIF (each frame after
    the first written as what changed) decodes to the frames given, an unchanged one included."""
    from PIL import Image

    palette = Palette()
    colours = ["#ffffff", "#000000", LINK_COLOR, SURFACE_COLOR, FORCE_COLOR, TARGET_COLOR, TRAIL_COLOR, POINT_COLOR]
    rgba = np.array([[[int(c[i : i + 2], 16) for i in (1, 3, 5)] + [255] for c in colours]], dtype=np.uint8)
    assert ["#{:02x}{:02x}{:02x}".format(*palette.rgb[i]) for i in palette.index(rgba)[0]] == colours
    first = np.zeros((6, 8), dtype=np.uint8)
    second = first.copy()
    second[2:4, 3:7] = 5
    frames = [first, second, second, first]
    gif = GifWriter(tmp_path / "a.gif", palette, 100)
    for frame in frames:
        gif.add(frame)
    gif.close()
    written = Image.open(tmp_path / "a.gif")
    assert getattr(written, "n_frames", 1) == len(frames)
    for k, frame in enumerate(frames):
        written.seek(k)
        assert np.array_equal(np.asarray(written.convert("RGB")), palette.rgb[frame]), k
        assert written.info["duration"] == 100


# --------------------------------------------------------------------------- comparison and old bags


def test_compare_writes_figures_and_the_summary_table(runs: dict[str, Path], tmp_path: Path) -> None:
    bags = [str(runs["braced"] / "bag"), str(runs["unbraced"] / "bag")]
    assert report_main([*bags, "--compare", "--output", str(tmp_path)]) == 0
    for name in ("compare_hand_error", "compare_brace_error", "compare_normal_force", "compare_energy"):
        png = tmp_path / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000, name
    table = (tmp_path / "compare.md").read_text()
    assert "| metric | braced | unbraced | unbraced / braced |" in table  # the first run is the baseline
    braced = json.loads((runs["braced"] / "summary.json").read_text())
    unbraced = json.loads((runs["unbraced"] / "summary.json").read_text())
    row = next(line for line in table.splitlines() if line.startswith("| energy consumed"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1:3] == [f"{braced['energy_consumed_j']:.4g}", f"{unbraced['energy_consumed_j']:.4g}"]
    assert float(cells[3]) == pytest.approx(unbraced["energy_consumed_j"] / braced["energy_consumed_j"], abs=1e-3)
    # Default output: the directory holding both runs.
    assert write_comparison(bags)[-1] == runs["braced"].parent / "compare.md"


def test_bag_without_scene_topics_still_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bag from before robot_description and /tf: plots and summary as before; animated only with --urdf."""
    from test_recorder_report import N_STEPS, write_bag_directly

    bag = tmp_path / "old" / "bag"
    write_bag_directly(bag, N_STEPS, ("elbow",))
    assert report_main([str(bag)]) == 0
    assert "no animation: the bag has no robot_description" in capsys.readouterr().err
    run_dir = tmp_path / "old"
    assert {p.name for p in run_dir.glob("*.png")} >= {"hand_y.png", "energy.png", "normal_force.png"}
    assert not (run_dir / "animation.gif").exists()
    assert json.loads((run_dir / "summary.json").read_text())["sim_time_s"] == pytest.approx((N_STEPS - 1) * 0.02)
    assert report_main([str(bag), "--urdf", str(PAPER_URDF), "--frame-interval", "1.0"]) == 0
    from PIL import Image

    assert getattr(Image.open(run_dir / "animation.gif"), "n_frames", 1) == 4  # 3.98 s at 1 s per frame
