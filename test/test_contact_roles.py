"""Braced contacts and kept-out frames apart, each surface drawn once, and a link inside a surface marked:
a bag written here with rosbags (the recorder's typestore) holds the paper arm at its start pose, its elbow
contact and three collision frames' pseudo-contacts on the same floor (``<frame>@elbow``), and the
``link_penetration`` topic the simulator publishes with robot.collision_geometry.

The hand-computed case (the issue's UR5 wrist, on the paper arm): at the start pose the elbow frame, the tip
of link 2, is on the floor, so link 2's cylinder (r = 0.03 m) is inside it around the frame. Link 2 runs from
the knee (0.2939, 0.4045) to the elbow (0.5878, 0) in (y, z), along d = (0.5878, -0.8090); the point of its
rim deepest in the floor is the elbow + r (-0.8090, -0.5878) = (0.5635, -0.0176): 17.6 mm inside.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_columns import BagBuilder, assert_columnar_is_general

from bracing_analysis.animation import POINT_COLOR, SURFACE_COLOR, ArmAnimation
from bracing_analysis.bag import read_series
from bracing_analysis.drawing import file_names
from bracing_analysis.figures import plot_figure
from bracing_core.contact_roles import BRACED, KEPT_OUT, by_role, kept_out_name, role, surface_owner

rr = pytest.importorskip("rerun")

from bracing_view import view  # noqa: E402

CONFIG = Path(__file__).resolve().parent.parent / "config"
JOINTS = ["joint1", "joint2", "joint3", "joint4"]
START = [-0.2 * math.pi, -0.6 * math.pi, 0.8 * math.pi, -0.4 * math.pi]
ELBOW = np.array([0.0, 0.5878, 0.0])
RADIUS = 0.03
DEEPEST = ELBOW + RADIUS * np.array([0.0, -0.8090, -0.5878])  # (0, 0.5635, -0.0176)
KEPT = [kept_out_name(frame, "elbow") for frame in ("link1_tip", "link3_tip", "hand_tip")]
STATES = 31  # 0 to 0.3 s, 10 ms apart
INSIDE_UNTIL_S = 0.15  # link 2 inside the floor at these states, then (as if lifted) out of it
TOUCH_S = (0.2, 0.25)  # link3_tip@elbow touches the floor between these


def _state(b: BagBuilder, name: str, frame: str, active: bool, point: Any, residual: float, force: float) -> Any:
    return b.store.types["bracing_msgs/msg/ContactState"](
        name, frame, active, b.point(*point), b.vector(0.0, 0.0, 1.0), force, 0.0, b.vector(0, 0, 0), residual
    )


def write_bag(path: Path) -> Path:
    b = BagBuilder()
    b.description((CONFIG / "paper_4link.urdf").read_text())
    contacts_type = "bracing_msgs/msg/Contacts"
    for k in range(STATES):
        ns, t = k * 10_000_000, k * 0.01
        state = b.store.types["sensor_msgs/msg/JointState"](
            b.header(ns), JOINTS, np.array(START), np.zeros(4), np.zeros(4)
        )
        b.add("/joint_states", "sensor_msgs/msg/JointState", state)
        touching = TOUCH_S[0] <= t < TOUCH_S[1]
        states = [_state(b, "elbow", "elbow", True, ELBOW, 0.0, 10.0)]
        states += [
            _state(b, name, name.split("@")[0], touching and j == 1, (0.0, 0.2 * j, 0.0), 0.0, 4.0 * touching)
            for j, name in enumerate(KEPT)
        ]
        b.add("/contacts", contacts_type, b.store.types[contacts_type](b.header(ns), states))
        b.wrench(ns, "elbow", 10.0)
        inside = t < INSIDE_UNTIL_S
        depth = -float(DEEPEST[2]) if inside else -0.02  # out of it: 2 cm away
        measured = _state(b, "link2@elbow", "link2", inside, DEEPEST, -depth, 0.0)
        b.add("/link_penetration", contacts_type, b.store.types[contacts_type](b.header(ns), [measured]))
    return b.write(path)


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_bag(tmp_path_factory.mktemp("roles") / "bag")


def test_roles_by_name() -> None:
    assert [role(n) for n in ("elbow", "lid", *KEPT)] == [BRACED, BRACED, KEPT_OUT, KEPT_OUT, KEPT_OUT]
    assert {surface_owner(n) for n in KEPT} == {"elbow"} and surface_owner("elbow") == "elbow"
    assert list(by_role({"elbow": 1, KEPT[0]: 2}, KEPT_OUT)) == [KEPT[0]]


def test_link_penetration_is_read_apart_from_the_contacts(bag: Path) -> None:
    series = assert_columnar_is_general(bag)  # bag.read_series as rosbags' per-message reading, bit for bit
    assert list(series.contacts) == ["elbow", *KEPT]  # link2@elbow is not a contact
    measured = series.link_penetration["elbow"]
    assert measured.name == "link2@elbow" and set(measured.link) == {"link2"}
    inside = measured.t < INSIDE_UNTIL_S - 1e-9
    assert np.array_equal(measured.inside, inside)
    assert measured.distance[inside] == pytest.approx(-0.0176, abs=1e-4)  # ~ r cos(36 deg): 17.6 mm inside
    assert measured.position[0] == pytest.approx(DEEPEST)


def test_the_report_keys_the_contacts_on_their_role(bag: Path) -> None:
    """summary.json: the elbow under contacts, the three frames under kept_out; the force plot has the braced
    contact only, and a kept-out frame that touched its surface gets a figure of its own."""
    from bracing_analysis.summary import compute_summary

    series = read_series(bag)
    summary = compute_summary(series)
    assert list(summary["contacts"]) == ["elbow"] and list(summary["kept_out"]) == KEPT
    assert summary["kept_out"][KEPT[1]]["normal_force_max_n"] == 4.0
    assert summary["kept_out"][KEPT[0]]["active_fraction"] == 0.0
    names = file_names(series, animation=False)
    assert "normal_force" in names and "kept_out_force" in names
    forces = plot_figure("normal_force", series).axes[0].get_legend_handles_labels()[1]
    assert forces == ["elbow f_n"]
    touched = plot_figure("kept_out_force", series).axes[0].get_legend_handles_labels()[1]
    assert touched == [f"{KEPT[1]} f_n"]  # the one that touched, not the two that never did


def test_the_viewer_draws_the_floor_once_and_marks_the_link_inside_it(bag: Path, tmp_path: Path) -> None:
    from rerun.chunk import RrdReader

    rrd = tmp_path / "run.rrd"
    counts = view.write_rrd(bag, rrd, period_s=0.0)  # every state drawn
    assert [key for key in counts if key.startswith("world/surfaces/")] == ["world/surfaces/elbow"]
    assert counts["world/surfaces/elbow"] == 1
    for name in KEPT:  # kept-out frames apart from the contacts, without a force plot
        assert counts[f"world/kept_out/{name}/point"] == STATES and f"world/contacts/{name}/point" not in counts
        assert f"plots/normal_force/{name}/f_n" not in counts
    inside = sum(1 for k in range(STATES) if k * 0.01 < INSIDE_UNTIL_S)
    assert counts["world/link_penetration/elbow/deepest"] == counts["world/link_penetration/elbow/depth"] == inside
    assert counts["world/link_penetration/elbow"] == STATES - inside  # cleared while no link is inside
    batches = [
        chunk.to_record_batch()
        for chunk in RrdReader(rrd).store().stream()
        if chunk.entity_path.replace("\\", "") == "/world/link_penetration/elbow/deepest"
    ]
    positions = [p for batch in batches for p in batch.column("Points3D:positions").to_pylist()]
    labels = [label for batch in batches for label in batch.column("Points3D:labels").to_pylist()]
    assert len(positions) == inside
    assert positions[0][0] == pytest.approx(DEEPEST, abs=1e-6)
    assert labels[0] == ["link2 18 mm inside elbow"]


def _close(pixel: np.ndarray, colour: str, tolerance: float = 40.0) -> bool:
    rgb = np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)], dtype=float)
    return float(np.linalg.norm(pixel[:3].astype(float) - rgb)) < tolerance


def test_the_animation_draws_the_floor_once_and_marks_the_link_inside_it(bag: Path) -> None:
    series = read_series(bag)
    animation = ArmAnimation(series, 0.1)  # frames at 0, 0.1, 0.2, 0.3 s
    ax = animation.figure().axes[0]
    bands = [p for p in ax.patches if not p.get_animated()]
    lines = [line for line in ax.lines if line.get_color() == SURFACE_COLOR]
    assert len(bands) == 1 and len(lines) == 1  # one floor, not one per collision frame
    assert [mark.label for mark in animation.inside] == [
        ["link2  17.6 mm inside elbow", "link2  17.6 mm inside elbow", "", ""]
    ]
    col, row = animation.pixel(DEEPEST)
    assert _close(np.array(animation.draw(0))[row, col], POINT_COLOR)  # marked while inside
    assert not _close(np.array(animation.draw(2))[row, col], POINT_COLOR)  # not once out
    kept = [c for c in animation.contacts if c.kept_out]
    assert [c.name for c in kept] == KEPT  # after the scenario's contact, drawn only while they touch
    assert np.isnan(kept[0].position).all() and np.isfinite(kept[1].position[2]).all()


def test_the_recorded_markers_draw_the_floor_once(tmp_path: Path) -> None:
    """contact_markers (RViz, Foxglove): the elbow's surface patch, point and force; a kept-out frame's point
    only (its surface is the elbow's, drawn with it)."""
    from bracing_core.typestore import bracing_typestore
    from bracing_recorder.scene import SURFACE_ID, SceneBuilder

    store = bracing_typestore()
    scene = SceneBuilder(store, ["elbow"], {})
    items: dict[str, bytes] = {}  # the first state's messages, as the recorder gets them
    for topic, raw in _messages(write_bag(tmp_path / "bag")):
        items.setdefault(topic, raw)
    out = scene.contacts(0, items["/contacts"]) + scene.wrench("elbow", 0, items["/contact_wrench/elbow"])
    (markers,) = [store.deserialize_cdr(d.data, "visualization_msgs/msg/MarkerArray") for d in out]
    surfaces = [m.ns for m in markers.markers if m.id == SURFACE_ID]
    assert surfaces == ["elbow"]
    assert {m.ns for m in markers.markers} == {"elbow", *KEPT}  # each kept-out frame's point is still drawn


def _messages(bag: Path) -> list[tuple[str, bytes]]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        return [(c.topic, raw) for c, _, raw in reader.messages()]
