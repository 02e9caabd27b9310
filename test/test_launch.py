"""launch/pair.launch.py: the run bracing-pair makes, from ros2 launch (for a system Jazzy).

No launch wheel exists on the package index, so the launch file itself is loaded only where
launch_ros is installed; what it hands the nodes is checked everywhere: it turns its arguments
into bracing-pair's command line and starts ``plan_run``'s processes, whose parameters are those
of a real bracing-pair run and whose executables are installed where ``ros2 launch`` finds them.
"""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest
from conftest import PAPER_YAML, SHORT_RUN_S

from bracing_bringup.pair import parse_args
from bracing_bringup.run_plan import PARAMS_FILE, plan_run, write_params

REPO_ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = REPO_ROOT / "src" / "bracing_bringup" / "launch" / "pair.launch.py"
INSTALL = REPO_ROOT / "install"


def test_launch_file_builds_where_launch_is_installed() -> None:
    pytest.importorskip("launch_ros", reason="launch_ros is not installed (no wheel exists; a system Jazzy has it)")
    spec = importlib.util.spec_from_file_location("pair_launch", LAUNCH_FILE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    declared = {action.name for action in description.entities if hasattr(action, "default_value")}
    assert declared == {"config", "output", "duration", "set"}


def test_launch_file_starts_the_pairs_plan() -> None:
    """Read from its source: launch_setup parses bracing-pair's arguments and starts plan_run's processes."""
    tree = ast.parse(LAUNCH_FILE.read_text())
    (setup,) = [node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "launch_setup"]
    called = {
        node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
        for node in ast.walk(setup)
        if isinstance(node, ast.Call)
    }
    assert {"parse_args", "plan_run", "write_params", "processes", "Node"} <= called


def test_its_parameters_are_the_pairs(runs: dict[str, Path], tmp_path: Path) -> None:
    """What the launch file writes for the nodes equals the params file of a real bracing-pair run."""
    options = parse_args(["--config", str(PAPER_YAML), "--output", str(tmp_path), "--duration", str(SHORT_RUN_S)])
    plan = plan_run(options)
    write_params(tmp_path / PARAMS_FILE, plan.node_params)
    assert (tmp_path / PARAMS_FILE).read_text() == (runs["braced"] / PARAMS_FILE).read_text()
    names = [process.name for process in plan.processes(tmp_path)]
    assert names == ["recorder", "controller", "simulator"]
    for process in plan.processes(tmp_path):
        executable = INSTALL / process.package / "lib" / process.package / process.executable
        assert executable.is_file(), f"ros2 launch would not find {executable}"
        assert str(tmp_path / PARAMS_FILE) in [*process.arguments, *process.ros_arguments]
