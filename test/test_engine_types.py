"""The engine's bound types are what mypy checks calls into the engine against: the build's stubs
(``_engine.pyi``, nanobind's stub generator) sit beside the module, and a wrong call is a type error."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import bracing_engine
import bracing_engine._engine as compiled

REPO_ROOT = Path(__file__).resolve().parents[1]

CALLS = """
import numpy as np
import bracing_engine as engine

robot = engine.Robot(urdf_path="robot.urdf", gravity=np.zeros(3))
spec = engine.SensorSpec(step=0.001, revolute=[True])
sensors = engine.Sensors(spec, 1)
reveal_type(sensors.delay(np.zeros(1)))
law = engine.Law(robot)  # a Robot is not a LawSpec
engine.SensorSpec(0.001, [True])  # keyword only
"""


def test_the_build_installs_the_engines_stubs_beside_it_marked_typed() -> None:
    """The stubs name every class the module binds, and the package says it is typed (PEP 561)."""
    package = Path(compiled.__file__).parent
    stubs = (package / "_engine.pyi").read_text()
    assert (package / "py.typed").exists()
    bound = [name for name in bracing_engine.__all__ if isinstance(getattr(compiled, name), type)]
    assert "LawSpec" in bound and "SensorSpec" in bound and "StepResult" in bound
    missing = [name for name in bound if f"class {name}" not in stubs]
    assert not missing, f"bound but not in _engine.pyi: {missing}"


def test_mypy_checks_calls_into_the_engine(tmp_path: Path) -> None:
    """With the project's mypy configuration a call into the engine is typed: a wrong argument and a positional
    spec are errors, and a method's answer has the stubs' type (not Any)."""
    calls = tmp_path / "calls.py"
    calls.write_text(CALLS)
    run = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(REPO_ROOT / "pyproject.toml"), "--no-incremental",
         str(calls)],
        cwd=REPO_ROOT, capture_output=True, text=True, check=False,
    )  # fmt: skip
    lines = run.stdout.splitlines()
    assert any(":9: error" in line and "LawSpec" in line for line in lines), run.stdout
    assert any(":10: error" in line for line in lines), run.stdout
    assert any(":8: note: Revealed type" in line and "ndarray" in line for line in lines), run.stdout
    assert sum(": error" in line for line in lines) == 2, run.stdout
