"""A URDF's meshes: ``package://`` paths found through the ament index, ``ROS_PACKAGE_PATH`` and
``robot.package_paths``; published on robot_description as ``file://`` paths, the ones not found named.
Every mesh file is written here (a unit cube as ASCII STL, a tetrahedron as Collada)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import PAPER_URDF, build_scenario

from bracing_core.meshes import find_package, resolve, resolved_description

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
    text = PAPER_URDF.read_text()
    meshes_of = [(STL_URI, f' scale="{scale}"'), (DAE_URI, ""), (GONE_URI, ""), (OTHER_GONE_URI, "")]
    parts = _GEOMETRY.split(text)
    assert len(parts) == len(meshes_of) + 1  # link1 to link4's cylinders
    meshes_xml = [f'<geometry><mesh filename="{uri}"{extra}/></geometry>' for uri, extra in meshes_of]
    text = "".join(part + mesh for part, mesh in zip(parts, [*meshes_xml, ""], strict=True))
    urdf = root / "urdf" / "arm.urdf"
    urdf.parent.mkdir()
    urdf.write_text(text)
    return urdf


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
