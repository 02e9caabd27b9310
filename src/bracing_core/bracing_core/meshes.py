"""The mesh files of a URDF: ``package://NAME/...``, ``file://...`` and plain paths found on this machine.

A published arm's URDF names its meshes ``package://NAME/meshes/...``. ``find_package`` looks NAME up
where ROS does, in this order: the ament index (``ament_index_python`` if installed, else each
``AMENT_PREFIX_PATH`` entry's ``share/NAME``), ``ROS_PACKAGE_PATH`` (each entry that is NAME, or holds
NAME/), then ``robot.package_paths`` (directories holding NAME/), then the Python environment's cmeel
prefix (``site-packages/cmeel.prefix/share/NAME``, where pip's cmeel wheels such as pinocchio and
example-robot-data install their share directories). A plain relative path is taken from the URDF's
directory.

``resolved_description`` writes each mesh it finds as a ``file://`` URI of its absolute path: what the
simulator publishes on ``robot_description``, so that RViz, Foxglove (desktop) and bracing-view
draw the meshes whatever package index they have (a package:// URI resolves only where NAME is
installed; a bag recorded here is then drawn with its meshes on this machine, not on one without
the files). A URDF without meshes is returned unchanged. The meshes it cannot find are named in
one warning (``missing_warning``); the viewers draw those links as capsules.

``visual_meshes`` lists the URDF's mesh visuals (link, filename, origin, scale) and ``read_mesh`` reads a
mesh file's triangles with coal (pinocchio's collision library; assimp: STL, OBJ, Collada, glTF, ...).
"""

from __future__ import annotations

import html
import os
import re
import sys
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
from numpy.typing import NDArray

PACKAGE = "package://"
FILE = "file://"

_MESH = re.compile(r"""(<mesh\b[^>]*?\bfilename\s*=\s*)(["'])(.*?)\2""", re.DOTALL)
"""A ``<mesh filename="...">`` attribute (the element's text before it, the quote, the value)."""


def _ament_share(name: str) -> Path | None:
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:  # not a ROS environment: the prefixes' share/NAME, as the index would have it
        for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
            share = Path(prefix) / "share" / name
            if prefix and share.is_dir():
                return share
        return None
    try:
        return Path(get_package_share_directory(name, print_warning=False))
    except (PackageNotFoundError, ValueError):
        return None


def _cmeel_share(name: str) -> Path | None:
    """``share/NAME`` of a cmeel prefix on ``sys.path`` (a pip wheel's ROS-style share directory)."""
    for entry in sys.path:
        share = Path(entry or ".") / "cmeel.prefix" / "share" / name
        if share.is_dir():
            return share
    return None


def find_package(name: str, package_paths: Sequence[str | Path] = ()) -> Path | None:
    """The directory of package ``name``: the ament index, then ``ROS_PACKAGE_PATH``, then
    ``package_paths`` (directories holding ``name/``), then the environment's cmeel prefix; None if
    none has it."""
    if not name or "/" in name or name in (".", ".."):
        return None
    share = _ament_share(name)
    if share is not None and share.is_dir():
        return share
    for root in (Path(e).expanduser() for e in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if e):
        if root.name == name and root.is_dir():
            return root
        if (root / name).is_dir():
            return root / name
    for held in (Path(e).expanduser() / name for e in package_paths):
        if held.is_dir():
            return held
    return _cmeel_share(name)


def resolve(uri: str, package_paths: Sequence[str | Path] = (), base: Path | None = None) -> Path | None:
    """The file a URDF mesh ``filename`` names (``package://``, ``file://``, or a path: a relative one
    from ``base``, the URDF's directory); None if it is not there (or another scheme, http://...)."""
    if uri.startswith(PACKAGE):
        name, _, rest = uri[len(PACKAGE) :].partition("/")
        package = find_package(name, package_paths)
        path = package / unquote(rest) if package is not None and rest else None
    elif uri.startswith(FILE):
        parsed = urlparse(uri)
        path = Path(unquote(parsed.netloc + parsed.path)) if parsed.netloc in ("", "localhost") else None
    elif "://" in uri:
        return None
    else:
        path = Path(uri).expanduser()
        if not path.is_absolute() and base is not None:
            path = base / path
    return path.resolve() if path is not None and path.is_file() else None


def mesh_uris(urdf: str) -> list[str]:
    """Every ``<mesh filename>`` of the URDF text (visual and collision), once each, in order."""
    return list(dict.fromkeys(html.unescape(m.group(3)) for m in _MESH.finditer(urdf)))


def resolved_description(
    urdf: str, package_paths: Sequence[str | Path] = (), base: Path | None = None
) -> tuple[str, list[str]]:
    """``urdf`` with each mesh it finds as a ``file://`` URI of the file (``resolve``), and the mesh
    filenames it cannot find. The text is returned as it is when it has no mesh to rewrite."""
    found: dict[str, str] = {}
    missing: list[str] = []
    for uri in mesh_uris(urdf):
        path = resolve(uri, package_paths, base)
        if path is None:
            missing.append(uri)
        elif path.as_uri() != uri:
            found[uri] = path.as_uri()
    if not found:
        return urdf, missing

    def rewritten(match: re.Match[str]) -> str:
        uri = found.get(html.unescape(match.group(3)))
        if uri is None:
            return match.group(0)
        return f"{match.group(1)}{match.group(2)}{html.escape(uri, quote=True)}{match.group(2)}"

    return _MESH.sub(rewritten, urdf), missing


def missing_warning(missing: Sequence[str]) -> str:
    """The one warning for the meshes that cannot be found (``missing``: their URDF filenames)."""
    return (
        f"{len(missing)} mesh file(s) of the URDF not found, those links drawn as capsules: {', '.join(missing)} "
        "(a package://NAME/... path is looked up in the ament index, ROS_PACKAGE_PATH, robot.package_paths and the "
        "Python environment's cmeel prefix, "
        "a relative one next to the URDF)"
    )


@dataclass(frozen=True)
class VisualMesh:
    """A ``<visual>`` of a URDF link whose geometry is a ``<mesh>``."""

    link: str
    uri: str  # its filename as written
    xyz: tuple[float, float, float]  # the visual's origin in the link frame [m]
    rpy: tuple[float, float, float]  # [rad]
    scale: tuple[float, float, float]


def visual_meshes(urdf: str) -> list[VisualMesh]:
    """Every mesh visual of the URDF text, link by link in document order."""
    out = []
    for link in ET.fromstring(urdf).iter("link"):
        for visual in link.iter("visual"):
            mesh = visual.find("geometry/mesh")
            if mesh is None:
                continue
            origin = visual.find("origin")
            xyz, rpy = (origin.get("xyz"), origin.get("rpy")) if origin is not None else (None, None)
            name, uri = link.get("name", ""), mesh.get("filename", "")
            scale = _three(mesh.get("scale"), 1.0)
            out.append(VisualMesh(name, uri, _three(xyz, 0.0), _three(rpy, 0.0), scale))
    return out


def _three(text: str | None, default: float) -> tuple[float, float, float]:
    """A URDF triple ("x y z"); ``default`` each where it is missing."""
    values = [float(v) for v in (text or "").split()]
    x, y, z = values if len(values) == 3 else [default] * 3
    return (x, y, z)


def read_mesh(path: Path) -> tuple[NDArray[np.float64], NDArray[np.uint32]] | None:
    """The vertices (n, 3) and triangles (m, 3) of a mesh file as coal's assimp reads it (STL, OBJ,
    Collada, glTF, ...; unscaled); None if it cannot (or coal is not installed)."""
    try:
        import coal  # pinocchio's collision library: imported where a mesh is read
    except ImportError:
        return None
    try:
        model = coal.MeshLoader().load(str(path))
    except Exception:  # assimp's refusals come as RuntimeError / ValueError
        return None
    vertices = np.asarray(model.vertices(), dtype=float).reshape(-1, 3)
    corners = [model.tri_indices(i) for i in range(model.num_tris)]  # coal's Triangle: indexed, not iterable
    triangles = np.array([[c[0], c[1], c[2]] for c in corners], dtype=np.uint32).reshape(-1, 3)
    if not len(vertices) or not len(triangles):
        return None
    return vertices, triangles
