"""The packages by job (docs/concepts/architecture.md, the package graph): dependencies run one way,
no module imports itself back through others, the ROS-free packages load no ROS, and each package.xml
names the project's packages its code imports (and no other)."""

from __future__ import annotations

import ast
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

ALLOWED = {
    "bracing_engine": set(),
    "bracing_core": {"bracing_engine"},
    "bracing_ros": {"bracing_core", "bracing_msgs"},
    "bracing_sim": {"bracing_core", "bracing_ros", "bracing_msgs", "bracing_rcl"},
    "bracing_rcl": set(),
    "bracing_controller": {"bracing_core", "bracing_ros", "bracing_msgs", "bracing_rcl"},
    "bracing_analysis": {"bracing_core"},
    "bracing_experiments": {"bracing_core", "bracing_analysis"},
    "bracing_mujoco": {"bracing_core", "bracing_ros", "bracing_msgs"},
    "bracing_recorder": {"bracing_core", "bracing_ros", "bracing_msgs", "bracing_analysis"},
    "bracing_view": {"bracing_core", "bracing_ros", "bracing_msgs", "bracing_analysis", "bracing_recorder"},
    "bracing_bringup": {"bracing_core", "bracing_ros", "bracing_analysis", "bracing_recorder", "bracing_view"},
}
"""Who may import whom: core <- ros <- nodes (sim, controller, mujoco, recorder); core <- analysis <- experiments;
ros + analysis <- recorder <- view; bringup above them all, starting and supervising."""
STARTED_NOT_IMPORTED = {"bracing_bringup": {"bracing_sim", "bracing_controller", "bracing_mujoco"}}
"""Packages a package starts as processes (bracing-pair, the launch file): in its package.xml, never imported."""
ROS_FREE = ("bracing_core", "bracing_analysis", "bracing_experiments")
PYTHON_PACKAGES = sorted(
    path.parent.name for path in SRC.glob("*/package.xml") if (path.parent / path.parent.name).is_dir()
)
"""Every package in src/ with Python modules (found on disk, whether or not ALLOWED lists it)."""
MAX_MODULE_LINES = 600
"""No module over this many lines: a longer one holds more than one job (split it)."""
MAX_PACKAGE_LINES = {"bracing_bringup": 2_000}
"""bringup starts and supervises; the recorder, the viewer and the MuJoCo robot are packages of their own."""


def modules(package: str) -> dict[str, Path]:
    """Every module of ``package`` by dotted name, its sub-packages' too (``bracing_core.schema.param``)."""
    root = SRC / package
    found = {".".join(path.relative_to(root).with_suffix("").parts): path for path in (root / package).rglob("*.py")}
    return {name.removesuffix(".__init__"): path for name, path in sorted(found.items())}


def imports(path: Path) -> set[str]:
    """Every module ``path`` imports, anywhere in it (a function's import counts as much as the top's)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found |= {f"{node.module}.{alias.name}" for alias in node.names}  # from package import module
    return found


def first_party(names: set[str]) -> set[str]:
    return {name.split(".")[0] for name in names if name.split(".")[0] in ALLOWED or name.startswith("bracing_msgs")}


@pytest.mark.parametrize("package", [p for p in ALLOWED if p != "bracing_engine"])
def test_dependencies_run_one_way(package: str) -> None:
    for module, path in modules(package).items():
        used = first_party(imports(path)) - {package}
        assert used <= ALLOWED[package], f"{module} imports {sorted(used - ALLOWED[package])}"


def test_no_import_cycles() -> None:
    everything = {name: path for package in ALLOWED for name, path in modules(package).items()}
    graph = {name: sorted(imports(path) & everything.keys() - {name}) for name, path in everything.items()}
    done: set[str] = set()

    def visit(name: str, trail: list[str]) -> None:
        if name in trail:
            pytest.fail("import cycle: " + " -> ".join([*trail[trail.index(name) :], name]))
        if name in done:
            return
        for used in graph[name]:
            visit(used, [*trail, name])
        done.add(name)

    for name in graph:
        visit(name, [])
    assert "bracing_analysis.report" in graph and "bracing_analysis.figures" in graph["bracing_analysis.compare"]


@pytest.mark.parametrize("package", ROS_FREE)
def test_ros_free_packages_load_no_ros(package: str) -> None:
    names = [name for name in modules(package) if not name.endswith("__init__")]
    code = f"import sys; import {', '.join(names)}; print(sorted(m for m in sys.modules if m.startswith('rcl')))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "[]"


@pytest.mark.parametrize("package", [p for p in ALLOWED if p != "bracing_engine"])
def test_package_xml_names_what_the_code_imports(package: str) -> None:
    declared = {
        element.text or ""
        for element in ET.parse(SRC / package / "package.xml").getroot()
        if element.tag in ("depend", "exec_depend")
    }
    used = set().union(*(first_party(imports(path)) for path in modules(package).values())) - {package}
    ours = {name for name in declared if name in ALLOWED or name == "bracing_msgs"}
    assert ours == used | STARTED_NOT_IMPORTED.get(package, set()), package


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_modules_stay_short(package: str) -> None:
    lines = {module: len(path.read_text().splitlines()) for module, path in modules(package).items()}
    too_long = {module: n for module, n in lines.items() if n > MAX_MODULE_LINES}
    assert not too_long, too_long
    assert sum(lines.values()) <= MAX_PACKAGE_LINES.get(package, sum(lines.values())), (package, sum(lines.values()))


def test_every_python_package_is_measured() -> None:
    """The size test sees every package with Python in it, sub-packages included (a module count of 0 would pass
    any limit)."""
    assert set(PYTHON_PACKAGES) == set(ALLOWED), set(PYTHON_PACKAGES) ^ set(ALLOWED)
    assert all(modules(package) for package in PYTHON_PACKAGES)
    assert "bracing_core.schema.typed" in modules("bracing_core")
