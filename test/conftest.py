"""Shared fixtures for the physics-core tests: the paper scenario, variants of it, and
memoised closed-loop runs (controller + simulator, in process, no ROS).

Variants are built from the scenario YAML's flat parameters: ``shared`` overrides go to
both the simulator's and the controller's parameters (the /** section), ``sim`` and
``ctl`` overrides only to one of them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bracing_controller.config import ControllerConfig
from bracing_controller.law import DecoupledController
from bracing_sim.config import Plant, SimulatorConfig, build_simulator
from bracing_sim.core.simulator import Energy, Simulator
from bracing_sim.params import load_params_file

REPO_ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO_ROOT / "config"
PAPER_YAML = CONFIG_DIR / "paper_4link.yaml"
PAPER_URDF = CONFIG_DIR / "paper_4link.urdf"

Overrides = Mapping[str, Any] | None


def node_params(node: str, shared: Overrides = None, own: Overrides = None) -> dict[str, Any]:
    """A fresh copy of the paper scenario's flat parameters for ``node``, with overrides."""
    params = load_params_file(PAPER_YAML, node)
    params.update(shared or {})
    params.update(own or {})
    return params


@dataclass
class Scenario:
    plant: Plant  # the simulator's plant
    sim: Simulator
    controller: DecoupledController | None  # built on its own plant, as in the node


def build_scenario(shared: Overrides = None, sim: Overrides = None, ctl: Overrides = None,
                   with_controller: bool = True) -> Scenario:
    plant, simulator = build_simulator(
        SimulatorConfig.from_params(node_params("bracing_simulator", shared, sim), [CONFIG_DIR]))
    controller = None
    if with_controller:
        controller = DecoupledController(
            ControllerConfig.from_params(node_params("bracing_controller", shared, ctl), [CONFIG_DIR]))
    return Scenario(plant, simulator, controller)


@dataclass
class Run:
    """A closed-loop run; row k is the state at the start of step k and what was sent/returned."""

    time: np.ndarray  # (N,)
    position: np.ndarray  # (N, n)
    velocity: np.ndarray  # (N, n)
    current: np.ndarray  # (N, n)
    command: np.ndarray  # (N, n)
    normal_force: np.ndarray  # (N, p)
    desired_normal_force: np.ndarray  # (p,)
    residual: np.ndarray  # (N, p), from the simulator's Derivative
    hand_error: np.ndarray  # (N,) |r_hd - r_h| [m]
    final_position: np.ndarray  # (n,)
    energy: Energy  # at the end

    def window(self, start: float = 0.0, stop: float = np.inf) -> np.ndarray:
        return (self.time >= start - 1e-12) & (self.time < stop - 1e-12)


def run_closed_loop(scenario: Scenario, duration: float) -> Run:
    sim, controller = scenario.sim, scenario.controller
    assert controller is not None
    steps = round(duration / sim.step_size)
    n, p = sim.n, len(scenario.plant.contact_set)
    rec = {key: np.zeros((steps, n)) for key in ("position", "velocity", "current", "command")}
    time, hand_error = np.zeros(steps), np.zeros(steps)
    normal_force, residual = np.zeros((steps, p)), np.zeros((steps, p))
    for k in range(steps):
        time[k] = sim.time
        q, dq = sim.position, sim.velocity
        out = controller.update(sim.time, q, dq)
        rec["position"][k], rec["velocity"][k], rec["current"][k] = q, dq, sim.current
        rec["command"][k] = out.command
        hand_error[k] = float(np.linalg.norm(out.hand_desired - out.hand_actual))
        derivative = sim.step(out.command)
        normal_force[k] = derivative.normal_force
        residual[k] = derivative.contacts.residual
    return Run(time, rec["position"], rec["velocity"], rec["current"], rec["command"], normal_force,
               controller.desired_normal_force.copy(), residual, hand_error, sim.position, sim.energy)


def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return tuple(sorted((k, _freeze(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


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
def closed_loop() -> Callable[..., Run]:
    """``closed_loop(shared=..., sim=..., ctl=..., duration=10.0)``: memoised over the session,
    so the 10 s paper runs are simulated once for all tests that use them."""
    cache: dict[Any, Run] = {}

    def run(shared: Overrides = None, sim: Overrides = None, ctl: Overrides = None, duration: float = 10.0) -> Run:
        key = (_freeze(shared or {}), _freeze(sim or {}), _freeze(ctl or {}), duration)
        if key not in cache:
            cache[key] = run_closed_loop(build_scenario(shared, sim, ctl), duration)
        return cache[key]

    return run
