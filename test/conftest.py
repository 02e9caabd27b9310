"""Shared fixtures for the physics-core tests: the paper scenario, variants of it, and
memoised closed-loop runs (controller + simulator, in process, no ROS).

Variants are built from the scenario YAML's flat parameters: ``shared`` overrides go to
both the simulator's and the controller's parameters (the /** section), ``sim`` and
``ctl`` overrides only to one of them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest
import ros_helpers

from bracing_core import overrides, rollout
from bracing_core.overrides import NodeOverrides
from bracing_core.rollout import ClosedLoop, Scenario, run_closed_loop

REPO_ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO_ROOT / "config"
PAPER_YAML = CONFIG_DIR / "paper_4link.yaml"
PAPER_URDF = CONFIG_DIR / "paper_4link.urdf"

Overrides = Mapping[str, Any] | None


def node_params(node: str, shared: Overrides = None, own: Overrides = None) -> dict[str, Any]:
    """A fresh copy of the paper scenario's flat parameters for ``node``, with overrides."""
    own_of = {"bracing_simulator": "simulator", "bracing_controller": "controller"}[node]
    layer = NodeOverrides(dict(shared or {}), **{own_of: dict(own or {})})
    return overrides.node_params(PAPER_YAML, layer)[node]


def build_scenario(
    shared: Overrides = None, sim: Overrides = None, ctl: Overrides = None, with_controller: bool = True
) -> Scenario:
    """The paper scenario, in process (the library's builder, bound to the paper's file)."""
    return rollout.build_scenario(PAPER_YAML, shared, sim, ctl, with_controller)


def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return tuple(sorted((k, _freeze(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


@pytest.fixture(autouse=True)
def _release_ros_domains() -> Iterator[None]:
    """Domain ids a test held for its ROS processes are free again once it ends."""
    yield
    ros_helpers.release_domains()


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT


@pytest.fixture
def sim_params() -> dict[str, Any]:
    """The paper scenario's simulator parameters (a fresh, modifiable copy)."""
    return node_params("bracing_simulator")


@pytest.fixture
def ctl_params() -> dict[str, Any]:
    """The paper scenario's controller parameters (a fresh, modifiable copy)."""
    return node_params("bracing_controller")


@pytest.fixture(scope="session")
def paper_params() -> Callable[..., dict[str, Any]]:
    """``paper_params(node, shared=None, own=None)``: fresh flat parameters of the paper scenario."""
    return node_params


@pytest.fixture(scope="session")
def scenario() -> Callable[..., Scenario]:
    """``scenario(shared=..., sim=..., ctl=..., with_controller=True)``: a fresh plant/sim/controller."""
    return build_scenario


@pytest.fixture(scope="session")
def closed_loop() -> Callable[..., ClosedLoop]:
    """``closed_loop(shared=..., sim=..., ctl=..., duration=10.0)``: memoised over the session,
    so the 10 s paper runs are simulated once for all tests that use them."""
    cache: dict[Any, ClosedLoop] = {}

    def run(
        shared: Overrides = None, sim: Overrides = None, ctl: Overrides = None, duration: float = 10.0
    ) -> ClosedLoop:
        key = (_freeze(shared or {}), _freeze(sim or {}), _freeze(ctl or {}), duration)
        if key not in cache:
            cache[key] = run_closed_loop(build_scenario(shared, sim, ctl), duration)
        return cache[key]

    return run


SHORT_RUN_S = 0.3


@pytest.fixture(scope="session")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two short bracing-pair runs of the paper scenario, braced and with no contacts at all (their
    run directories), shared by the tests that read recorded bags."""
    root = tmp_path_factory.mktemp("runs")
    out = {}
    for name, extra in (("braced", ()), ("unbraced", ("--set", "contacts.names=[]"))):
        done = ros_helpers.run(ros_helpers.pair_argv(root / name, "--duration", str(SHORT_RUN_S), *extra), timeout=300)
        assert done.returncode == 0, done.stdout + done.stderr
        out[name] = root / name
    return out
