"""A URDF's meshes: ``package://`` paths found through the ament index, ``ROS_PACKAGE_PATH`` and
``robot.package_paths``; published on robot_description as ``file://`` paths; drawn by bracing-view (STL as
an Asset3D, Collada through coal as a Mesh3D); the ones not found named in one warning, drawn as capsules.
Every mesh file is written here (a unit cube as ASCII STL, a tetrahedron as Collada)."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import ros_helpers
from conftest import PAPER_URDF, build_scenario

from bracing_analysis.animation import LINK_COLOR, MESH_ALPHA, ArmAnimation
from bracing_analysis.bag import read_series
from bracing_core.meshes import find_package, resolve, resolved_description

rr = pytest.importorskip("rerun")

from rerun.chunk import RrdReader  # noqa: E402

from bracing_view import view  # noqa: E402

PACKAGE = "bracing_test_arm"
STL_URI = f"package://{PACKAGE}/meshes/link.stl"
DAE_URI = f"package://{PACKAGE}/meshes/link.dae"
GONE_URI = f"package://{PACKAGE}/meshes/gone.dae"
OTHER_GONE_URI = "package://no_such_package/meshes/hand.stl"
STL_SCALE = (0.2, 0.2, 0.5)  # the unit cube as link1's 20 cm x 20 cm x 50 cm box

_GEOMETRY = re.compile(r"<geometry>.*?</geometry>")

DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="tet"><mesh>
    <source id="p"><float_array id="pa" count="12">0 0 0 0.05 0 0 0 0.05 0 0 0 0.5</float_array>
      <technique_common><accessor source="#pa" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="4"><input semantic="VERTEX" source="#v" offset="0"/><p>0 2 1 0 1 3 0 3 2 1 2 3</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#tet"/></node></visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def _cube_stl() -> str:
    """A unit cube about the origin as ASCII STL (12 triangles)."""
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float) - 0.5
    quads = [(0, 2, 6, 4), (1, 5, 7, 3), (0, 4, 5, 1), (2, 3, 7, 6), (0, 1, 3, 2), (4, 6, 7, 5)]
    lines = ["solid cube"]
    for a, b, c, d in quads:
        normal = np.cross(corners[b] - corners[a], corners[c] - corners[a])
        for tri in ((a, b, c), (a, c, d)):
            lines += [f"  facet normal {' '.join(f'{v:g}' for v in normal)}", "    outer loop"]
            lines += [f"      vertex {' '.join(f'{v:g}' for v in corners[k])}" for k in tri]
            lines += ["    endloop", "  endfacet"]
    return "\n".join([*lines, "endsolid cube", ""])


def write_arm(root: Path) -> Path:
    """The paper's arm with meshes: link1 an STL box (scaled), link2 a Collada tetrahedron, link3 a Collada
    file that is not there and link4 a mesh of a package that is nowhere. The package (``root/PACKAGE``)
    sits beside the URDF's directory (``root/urdf``): ``robot.package_paths: [..]`` finds it."""
    meshes = root / PACKAGE / "meshes"
    meshes.mkdir(parents=True)
    (meshes / "link.stl").write_text(_cube_stl())
    (meshes / "link.dae").write_text(DAE)
    scale = " ".join(f"{v:g}" for v in STL_SCALE)
    text = re.sub(r"\s*<collision>.*?</collision>", "", PAPER_URDF.read_text(), flags=re.DOTALL)  # visuals only
    meshes_of = [(STL_URI, f' scale="{scale}"'), (DAE_URI, ""), (GONE_URI, ""), (OTHER_GONE_URI, "")]
    parts = _GEOMETRY.split(text)
    assert len(parts) == len(meshes_of) + 1  # link1 to link4's cylinders
    meshes_xml = [f'<geometry><mesh filename="{uri}"{extra}/></geometry>' for uri, extra in meshes_of]
    text = "".join(part + mesh for part, mesh in zip(parts, [*meshes_xml, ""], strict=True))
    urdf = root / "urdf" / "arm.urdf"
    urdf.parent.mkdir()
    urdf.write_text(text)
    return urdf


def _rows(rrd: Path, prefix: str) -> dict[str, dict[str, Any]]:
    """The components (``Archetype:field``) last logged to each entity under ``prefix`` in a .rrd."""
    rows: dict[str, dict[str, Any]] = {}
    for chunk in RrdReader(rrd).store().stream():
        if chunk.entity_path.startswith(prefix):
            batch = chunk.to_record_batch()
            components = [name for name in batch.schema.names if ":" in name]  # not the timelines
            rows.setdefault(chunk.entity_path, {}).update({n: batch.column(n).to_pylist()[-1] for n in components})
    return rows


def _warnings(text: str) -> list[str]:
    return [line for line in text.splitlines() if "not found" in line and "mesh" in line]


# --------------------------------------------------------------------------- where a package is found


def test_packages_are_found_in_ross_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first, second = tmp_path / "ros_package_path", tmp_path / "package_paths"
    for root in (first, second):
        (root / PACKAGE / "meshes").mkdir(parents=True)
        (root / PACKAGE / "meshes" / "link.stl").write_text(_cube_stl())
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    assert find_package(PACKAGE) is None
    assert find_package(PACKAGE, [second]) == second / PACKAGE  # robot.package_paths
    monkeypatch.setenv("ROS_PACKAGE_PATH", f"{tmp_path / 'elsewhere'}:{first}")
    assert find_package(PACKAGE, [second]) == first / PACKAGE  # ROS_PACKAGE_PATH comes first
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(first / PACKAGE))  # an entry that is the package itself
    assert find_package(PACKAGE) == first / PACKAGE
    # The ament index: an installed package of this workspace (its share directory).
    assert (find_package("bracing_bringup") or Path()).joinpath("package.xml").is_file()
    stl = first / PACKAGE / "meshes" / "link.stl"
    assert resolve(STL_URI) == stl
    assert resolve(stl.as_uri()) == stl  # file://
    assert resolve("meshes/link.stl", base=first / PACKAGE) == stl  # a plain path, from the URDF's directory
    assert resolve(GONE_URI) is None and resolve("https://example.com/link.stl") is None


def test_robot_description_names_found_meshes_by_file_uri(tmp_path: Path) -> None:
    """What the simulator publishes: the meshes found as file:// paths (RViz, Foxglove and bracing-view
    need no package index), the others as written and named; the paper's URDF as it was, byte for byte."""
    urdf = write_arm(tmp_path)
    plant = build_scenario(shared={"robot.urdf": str(urdf), "robot.package_paths": [".."]}, with_controller=False).plant
    text, missing = plant.description()
    meshes = (tmp_path / PACKAGE / "meshes").resolve()
    assert f'filename="{(meshes / "link.stl").as_uri()}" scale="0.2 0.2 0.5"' in text
    assert f'filename="{(meshes / "link.dae").as_uri()}"' in text
    assert missing == [GONE_URI, OTHER_GONE_URI] and f'filename="{GONE_URI}"' in text
    assert text.replace((meshes / "link.stl").as_uri(), STL_URI).replace((meshes / "link.dae").as_uri(), DAE_URI) == (
        urdf.read_text()
    )  # nothing else touched
    paper = build_scenario(with_controller=False).plant
    assert paper.description() == (PAPER_URDF.read_text(), [])
    assert resolved_description("<robot/>") == ("<robot/>", [])


# --------------------------------------------------------------------------- bracing-view draws them


def test_view_draws_package_meshes_and_warns_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot_description with package:// meshes (a foreign publisher's): found on ROS_PACKAGE_PATH,
    the STL drawn as itself, the Collada file as its triangles, the missing ones in one warning and not drawn."""
    urdf = write_arm(tmp_path)
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path))
    rrd = tmp_path / "robot.rrd"
    recording = view.new_recording()
    recording.save(str(rrd))
    feed = view.Feed(recording, 0.0)
    feed.message("robot_description", SimpleNamespace(data=urdf.read_text()))
    recording.flush()
    recording.disconnect()
    rows = _rows(rrd, "/world/robot/")
    stl = rows["/world/robot/link1/visual_0/shape"]
    assert bytes(stl["Asset3D:blob"][0]) == (tmp_path / PACKAGE / "meshes" / "link.stl").read_bytes()
    assert stl["Asset3D:media_type"] == ["model/stl"]
    assert rows["/world/robot/link1/visual_0"]["Transform3D:scale"][0] == pytest.approx(STL_SCALE)
    dae = rows["/world/robot/link2/visual_0/shape"]
    vertices = np.array(dae["Mesh3D:vertex_positions"])
    assert sorted(map(tuple, vertices.round(6).tolist())) == [(0, 0, 0), (0, 0, 0.5), (0, 0.05, 0), (0.05, 0, 0)]
    assert len(dae["Mesh3D:triangle_indices"]) == 4
    for link in ("link3", "link4"):  # not found: the skeleton's capsule only
        assert not any(path.startswith(f"/world/robot/{link}/visual") for path in rows)
    warned = _warnings(capsys.readouterr().err)
    assert len(warned) == 1 and GONE_URI in warned[0] and OTHER_GONE_URI in warned[0]
    assert feed.warnings == [warned[0].split("warning: ", 1)[1]]


def test_a_run_with_meshes_is_drawn_with_them(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """bracing-pair with robot.package_paths: one warning in the simulator's log for the meshes it cannot
    find; the bag's robot_description points at the files found, so bracing-view draws them from the bag
    with no package index at all, and the animation shades each mesh's outline."""
    urdf = write_arm(tmp_path / "arm")
    out = tmp_path / "run"
    extra = ("--duration", "0.1", "--set", f"robot.urdf={urdf}", "--set", "robot.package_paths=[..]")
    done = ros_helpers.run(ros_helpers.pair_argv(out, *extra), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    warned = _warnings((out / "logs" / "simulator.log").read_text())
    assert len(warned) == 1 and GONE_URI in warned[0] and OTHER_GONE_URI in warned[0] and "link.stl" not in warned[0]
    counts = view.write_rrd(out / "bag", tmp_path / "run.rrd", period_s=0.05)
    assert counts["world/robot/link1/visual_0/shape"] == counts["world/robot/link2/visual_0/shape"] == 1
    rows = _rows(tmp_path / "run.rrd", "/world/robot/")
    stl = (tmp_path / "arm" / PACKAGE / "meshes" / "link.stl").read_bytes()
    assert bytes(rows["/world/robot/link1/visual_0/shape"]["Asset3D:blob"][0]) == stl
    assert "Mesh3D:vertex_positions" in rows["/world/robot/link2/visual_0/shape"]
    assert len(_warnings(capsys.readouterr().err)) == 1  # the viewer's own, for the same two
    # The animation: link1's box shades its outline, 20 cm wide, where the paper's arm has a line only.
    assert (out / "animation.gif").is_file()
    series = read_series(out / "bag")
    meshed, plain = ArmAnimation(series), ArmAnimation(series, urdf=PAPER_URDF.read_text())
    assert [m.row for m in meshed.outlines] == [meshed.poses.body_names.index(link) for link in ("link1", "link2")]
    assert not plain.outlines
    link1 = meshed.poses.body_names.index("link1")
    meshed.poses.update(meshed.poses.configuration(series.joint_names, series.joint_position[0]))
    placement = meshed.poses.data.oMf[meshed.poses.body_ids[link1]]
    inside = placement.act(np.array([0.0, 0.07, 0.25]))  # 7 cm beside the link's axis, in the arm's plane
    outside = placement.act(np.array([0.0, 0.13, 0.25]))  # 3 cm beyond the box
    shaded = meshed.draw(0)[meshed.pixel(inside)[::-1]][:3].astype(int)
    assert min(plain.draw(0)[plain.pixel(inside)[::-1]][:3]) >= 240  # white (or a grid line's grey)
    blue = np.array([int(LINK_COLOR[i : i + 2], 16) for i in (1, 3, 5)])
    faded = (1 - MESH_ALPHA) * 255 + MESH_ALPHA * blue  # the links' blue over white
    assert shaded == pytest.approx(faded, abs=4)
    assert min(meshed.draw(0)[meshed.pixel(outside)[::-1]][:3]) >= 240
