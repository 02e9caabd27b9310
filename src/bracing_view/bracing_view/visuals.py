"""A robot's URDF visuals as rerun shapes (bracing-view draws them on the robot's links): boxes, cylinders,
spheres and the meshes found."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from bracing_core.meshes import missing_warning, read_mesh
from bracing_core.meshes import resolve as resolve_mesh

VISUAL_COLOR = [150, 170, 210]
ASSET_SUFFIXES = (".stl", ".obj", ".glb", ".gltf")
"""The mesh files rerun's Asset3D draws as they are; others (Collada .dae, ...) are read by coal (assimp)
into a Mesh3D."""


class Visuals:
    """A URDF's visuals as rerun shapes: per link, (shape, origin (xyz, quaternion xyzw), scale or None).
    Boxes, cylinders and spheres; meshes found (``bracing_core.meshes.resolve``: file://, package:// through
    the ament index and ROS_PACKAGE_PATH) as an Asset3D, or a Mesh3D where rerun cannot read the file. A
    link whose mesh is not found, or cannot be read, is drawn as the skeleton's capsule alone."""

    def __init__(self, urdf: str) -> None:
        self.links: dict[str, list[tuple[Any, list[float], list[float] | None]]] = {}
        self.missing: list[str] = []  # mesh filenames not found
        self.unread: list[str] = []  # mesh files found that nothing here reads
        root = ET.fromstring(urdf)
        self.materials = {m.get("name", ""): _rgba(m) for m in root.findall("material")}
        for link in root.iter("link"):
            for visual in link.iter("visual"):
                geometry = visual.find("geometry")
                if geometry is None:
                    continue
                origin = visual.find("origin")
                xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
                rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
                shape, scale = self._shape(geometry, visual.find("material"))
                if shape is not None:
                    self.links.setdefault(link.get("name", ""), []).append((shape, [*xyz, *_quat(rpy)], scale))

    def _shape(self, geometry: ET.Element, material: ET.Element | None) -> tuple[Any, list[float] | None]:
        mesh = geometry.find("mesh")
        if mesh is None:
            return _shape(geometry), None
        uri = mesh.get("filename", "")
        path = resolve_mesh(uri)
        if path is None:
            self.missing.append(uri)
            return None, None
        color = self._color(material)
        shape = _mesh_shape(path, color)
        if shape is None:
            self.unread.append(uri)
            return None, None
        return shape, [float(v) for v in mesh.get("scale", "1 1 1").split()]

    def _color(self, material: ET.Element | None) -> list[int] | None:
        """The visual's colour (its own, or the robot's named material), 0-255 RGBA; None if it has none."""
        if material is None:
            return None
        return _rgba(material) or self.materials.get(material.get("name", ""))

    def warnings(self) -> list[str]:
        out = [missing_warning(self.missing)] if self.missing else []
        if self.unread:
            out.append(f"mesh file(s) not drawn (no reader for them here), drawn as capsules: {', '.join(self.unread)}")
        return out


def _rgba(material: ET.Element) -> list[int] | None:
    color = material.find("color")
    if color is None:
        return None
    values = [float(v) for v in color.get("rgba", "").split()]
    return [round(255 * min(max(v, 0.0), 1.0)) for v in values] if len(values) == 4 else None


def _mesh_shape(path: Path, color: list[int] | None) -> Any:
    """A mesh file as rerun draws it: STL, OBJ, glTF as an Asset3D (its bytes), any other format coal's
    assimp reads (Collada .dae, ...) as a Mesh3D of its triangles; None if it cannot be read."""
    if path.suffix.lower() in ASSET_SUFFIXES:
        plain = path.suffix.lower() == ".stl"  # no material of its own: the URDF's colour, else the capsules'
        return rr.Asset3D(path=path, albedo_factor=color or (VISUAL_COLOR if plain else None))
    read = read_mesh(path)
    if read is None:
        return None
    vertices, triangles = read
    return rr.Mesh3D(
        vertex_positions=vertices.astype(np.float32), triangle_indices=triangles, albedo_factor=color or VISUAL_COLOR
    )


def _shape(geometry: ET.Element) -> Any:
    color = VISUAL_COLOR
    box, cylinder, sphere = geometry.find("box"), geometry.find("cylinder"), geometry.find("sphere")
    if box is not None:
        size = [float(v) / 2 for v in box.get("size", "0 0 0").split()]
        return rr.Boxes3D(half_sizes=[size], colors=[color])
    if cylinder is not None:
        return rr.Cylinders3D(
            lengths=[float(cylinder.get("length", 0))], radii=[float(cylinder.get("radius", 0))], colors=[color]
        )
    if sphere is not None:
        return rr.Ellipsoids3D(half_sizes=[[float(sphere.get("radius", 0))] * 3], colors=[color], fill_mode="solid")
    return None


def _quat(rpy: Sequence[float]) -> list[float]:
    """URDF roll-pitch-yaw as a quaternion x, y, z, w."""
    r, p, y = (v / 2 for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return [
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    ]
