"""Spheres and cylinders are drawn as spheres and cylinders, in contact_markers
(visualization_msgs SPHERE / CYLINDER) and in the animation; planes as before.

One short real bracing-pair run (0.3 s, over DDS) of the paper's arm with its elbow braced on a
sphere and a cylinder over its hand as an obstacle: the recorder reads the surfaces from the nodes'
params file, draws them and keeps them in the bag, where the animation finds them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml
from ros_helpers import PAPER_YAML, pair_argv, run
from rosbags.highlevel import AnyReader

from bracing_analysis.animation import ArmAnimation
from bracing_analysis.bag import read_series
from bracing_analysis.surfaces import Shape
from bracing_core.typestore import bracing_typestore
from bracing_recorder.scene import SceneBuilder

PAPER_URDF = PAPER_YAML.parent / "paper_4link.urdf"
Q0 = np.array([-0.2, -0.6, 0.8, -0.4]) * np.pi
RADIUS = 0.3
SPHERE, CYLINDER, CUBE = 2, 3, 1  # visualization_msgs/Marker types
LID_AXIS_POINT = (0.0, 1.0633, 1.2)  # the cylinder over the hand: axis along x, 0.25 m above the hand


class _QuotingDumper(yaml.SafeDumper):
    """Quotes the axis names: rcl reads YAML 1.1, where a bare y is a boolean."""


_QuotingDumper.add_representer(
    str,
    lambda dumper, text: dumper.represent_scalar("tag:yaml.org,2002:str", text, style="'" if len(text) == 1 else None),
)


def _elbow() -> np.ndarray:
    model = pin.buildModelFromUrdf(str(PAPER_URDF))
    data = model.createData()
    pin.framesForwardKinematics(model, data, Q0)
    return np.array(data.oMf[model.getFrameId("elbow")].translation)


@pytest.fixture(scope="module")
def curved_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The run directory of the paper's arm braced on a sphere under its elbow, a cylinder above its hand."""
    root = tmp_path_factory.mktemp("curved")
    document = yaml.safe_load(PAPER_YAML.read_text())
    shared = document["/**"]["ros__parameters"]
    shared["robot"]["urdf"] = str(PAPER_URDF)
    centre = _elbow() - np.array([0.0, 0.0, RADIUS])  # the elbow on top of the sphere
    elbow = shared["contacts"]["elbow"]
    elbow.update(surface="sphere", center=centre.tolist(), radius=RADIUS)
    shared["contacts"]["names"] = ["elbow", "lid"]
    shared["contacts"]["lid"] = {  # an obstacle (no desired force): the hand starts 0.25 m below it
        "frame": "hand",
        "surface": "cylinder",
        "point": list(LID_AXIS_POINT),
        "axis": [1.0, 0.0, 0.0],
        "radius": RADIUS,
    }
    config = root / "curved.yaml"
    config.write_text(yaml.dump(document, Dumper=_QuotingDumper, sort_keys=False))
    out = root / "run"
    done = run(pair_argv(out, "--duration", "0.3", config=config), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def _markers(bag: Path) -> list[Any]:
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/contact_markers"]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections)]


def test_the_bag_draws_a_sphere_and_a_cylinder(curved_run: Path) -> None:
    arrays = _markers(curved_run / "bag")
    assert len(arrays) == 301
    centre = _elbow() - np.array([0.0, 0.0, RADIUS])
    for array in (arrays[0], arrays[-1]):  # the surfaces stay put
        surfaces = {m.ns: m for m in array.markers if m.id == 0}
        sphere, cylinder = surfaces["elbow"], surfaces["lid"]
        assert sphere.type == SPHERE
        assert [sphere.scale.x, sphere.scale.y, sphere.scale.z] == [2 * RADIUS] * 3  # a diameter
        position = sphere.pose.position
        assert [position.x, position.y, position.z] == pytest.approx(centre.tolist(), abs=1e-12)
        assert cylinder.type == CYLINDER
        assert [cylinder.scale.x, cylinder.scale.y] == [2 * RADIUS] * 2
        position, turn = cylinder.pose.position, cylinder.pose.orientation
        assert [position.x, position.y, position.z] == pytest.approx(list(LID_AXIS_POINT), abs=1e-9)
        half = math.sqrt(0.5)  # the marker's z turned onto the axis, x: 90 degrees about y
        assert [turn.x, turn.y, turn.z, turn.w] == pytest.approx([0.0, half, 0.0, half], abs=1e-12)
    series = read_series(curved_run / "bag")  # the bag keeps the surfaces for the report
    assert series.surfaces["elbow"].kind == "sphere" and series.surfaces["elbow"].radius == RADIUS
    assert series.surfaces["lid"] == Shape("cylinder", point=LID_AXIS_POINT, axis=(1.0, 0.0, 0.0), radius=RADIUS)


def _close(pixel: np.ndarray, colour: str, tolerance: float = 40.0) -> bool:
    rgb = np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)], dtype=float)
    return float(np.linalg.norm(pixel[:3].astype(float) - rgb)) < tolerance


def test_the_animation_draws_the_sphere_and_cylinders_as_such(curved_run: Path) -> None:
    series = read_series(curved_run / "bag")
    elbow = _elbow()
    inside = elbow + np.array([0.0, 0.0, -0.15])  # in the sphere's disc, below its tangent plane's band
    beside = elbow + np.array([0.0, RADIUS + 0.05, -0.15])  # outside the disc, as deep
    grey, white = "#cccccc", "#ffffff"  # the surface colour at half opacity over white, and nothing

    def pixels(shapes: dict[str, Shape]) -> list[np.ndarray]:
        series.surfaces = shapes
        animation = ArmAnimation(series, 0.1)
        frame = np.array(animation.draw(0))
        return [frame[row, col] for col, row in (animation.pixel(inside), animation.pixel(beside))]

    recorded = dict(series.surfaces)
    disc, outside = pixels(recorded)
    assert _close(disc, grey) and _close(outside, white), (disc, outside)
    # Without the surfaces (an older bag): the tangent plane, as before; nothing that deep.
    disc, outside = pixels({})
    assert _close(disc, white) and _close(outside, white), (disc, outside)
    # A cylinder seen end on is a disc too; one whose axis lies in the view, a band along it.
    centre = tuple(recorded["elbow"].center)
    disc, outside = pixels({**recorded, "elbow": Shape("cylinder", point=centre, axis=(1.0, 0.0, 0.0), radius=RADIUS)})
    assert _close(disc, grey) and _close(outside, white), (disc, outside)
    band, along = pixels({**recorded, "elbow": Shape("cylinder", point=centre, axis=(0.0, 1.0, 0.0), radius=RADIUS)})
    assert _close(band, grey) and _close(along, grey), (band, along)


def test_the_scene_draws_planes_as_before_and_solids_where_they_are() -> None:
    """SceneBuilder alone: a plane's CUBE patch, a sphere's SPHERE and a cylinder's CYLINDER, from the
    contacts and wrenches it is fed; without shapes, every surface is its tangent patch (as before)."""
    store = bracing_typestore()
    t = store.types
    point, vector = t["geometry_msgs/msg/Point"], t["geometry_msgs/msg/Vector3"]
    header = t["std_msgs/msg/Header"](t["builtin_interfaces/msg/Time"](0, 0), "world")
    names = ["floor", "ball", "pipe"]
    state = t["bracing_msgs/msg/ContactState"]
    contacts = t["bracing_msgs/msg/Contacts"](
        header,
        [
            state(n, "elbow", True, point(0.0, 1.0, 0.0), vector(0.0, 0.0, 1.0), 10.0, 0.0, vector(0.0, 0.0, 0.0), 0.0)
            for n in names
        ],
    )
    wrench = t["geometry_msgs/msg/WrenchStamped"](
        header, t["geometry_msgs/msg/Wrench"](vector(0.0, 0.0, 10.0), vector(0.0, 0.0, 0.0))
    )
    shapes = {
        "floor": Shape("plane"),
        "ball": Shape("sphere", center=(0.0, 1.0, -0.5), radius=0.5),
        "pipe": Shape("cylinder", point=(3.0, 1.0, -0.2), axis=(1.0, 0.0, 0.0), radius=0.2),
    }
    drawn = {}
    for given in (shapes, None):
        scene = SceneBuilder(store, names, given)
        out = scene.contacts(0, bytes(store.serialize_cdr(contacts, "bracing_msgs/msg/Contacts")))
        for name in names:
            out += scene.wrench(name, 0, bytes(store.serialize_cdr(wrench, "geometry_msgs/msg/WrenchStamped")))
        (markers,) = [store.deserialize_cdr(d.data, "visualization_msgs/msg/MarkerArray") for d in out]
        drawn[given is None] = {m.ns: m for m in markers.markers if m.id == 0}
    solid = drawn[False]
    assert solid["floor"].type == CUBE and solid["floor"].scale.z == pytest.approx(0.002)
    assert solid["ball"].type == SPHERE and solid["ball"].scale.x == 1.0
    assert [solid["ball"].pose.position.y, solid["ball"].pose.position.z] == [1.0, -0.5]
    assert solid["pipe"].type == CYLINDER and solid["pipe"].scale.x == pytest.approx(0.4)
    position = solid["pipe"].pose.position
    assert [position.x, position.y, position.z] == pytest.approx([0.0, 1.0, -0.2])  # nearest the contact
    assert {m.type for m in drawn[True].values()} == {CUBE}  # no shapes: tangent patches, as before
