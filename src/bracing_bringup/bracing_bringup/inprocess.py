"""The experiment without ROS: the same plant, simulator and controller cores the nodes run,
stepped in one process (tests, benchmarks, parameter sweeps).

    scenario = build_scenario("config/paper_4link.yaml", shared={"input_mode": "torque"})
    run = run_closed_loop(scenario, duration=10.0)

``shared`` overrides go to both nodes' parameters (the /** section of the file), ``sim``
and ``ctl`` to one of them; the step loop is the lockstep protocol of the nodes: the
controller answers state k, the simulator steps with that command held.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bracing_controller.config import ControllerConfig
from bracing_controller.law import DecoupledController
from bracing_sim.config import Plant, SimulatorConfig, build_simulator
from bracing_sim.core.simulator import Energy, Simulator
from bracing_sim.params import load_params_file

Overrides = Mapping[str, Any] | None


def node_params(config: str | Path, node: str, shared: Overrides = None, own: Overrides = None) -> dict[str, Any]:
    """The flat parameters ``node`` gets from the scenario file, with overrides applied."""
    params = load_params_file(config, node)
    params.update(shared or {})
    params.update(own or {})
    return params


@dataclass
class Scenario:
    plant: Plant  # the simulator's plant
    sim: Simulator
    controller: DecoupledController | None  # built on its own plant, as in the node


def build_scenario(
    config: str | Path,
    shared: Overrides = None,
    sim: Overrides = None,
    ctl: Overrides = None,
    with_controller: bool = True,
) -> Scenario:
    search = [Path(config).resolve().parent]
    plant, simulator = build_simulator(
        SimulatorConfig.from_params(node_params(config, "bracing_simulator", shared, sim), search)
    )
    controller = None
    if with_controller:
        controller = DecoupledController(
            ControllerConfig.from_params(node_params(config, "bracing_controller", shared, ctl), search)
        )
    return Scenario(plant, simulator, controller)


@dataclass
class Run:
    """A closed-loop run; row k is the state at the start of step k and what was sent/returned."""

    time: np.ndarray  # (N,) [s]
    position: np.ndarray  # (N, n) [rad]
    velocity: np.ndarray  # (N, n) [rad/s]
    current: np.ndarray  # (N, n) [A]
    command: np.ndarray  # (N, n) [V] or [N m]
    normal_force: np.ndarray  # (N, p) [N]
    desired_normal_force: np.ndarray  # (p,) [N]
    residual: np.ndarray  # (N, p) [m]
    hand_error: np.ndarray  # (N,) |r_hd - r_h| [m]
    final_position: np.ndarray  # (n,)
    energy: Energy  # at the end

    def window(self, start: float = 0.0, stop: float = np.inf) -> np.ndarray:
        return np.asarray((self.time >= start - 1e-12) & (self.time < stop - 1e-12))


def run_closed_loop(scenario: Scenario, duration: float) -> Run:
    sim, controller = scenario.sim, scenario.controller
    if controller is None:
        raise ValueError("run_closed_loop needs a scenario built with a controller")
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
    return Run(
        time,
        rec["position"],
        rec["velocity"],
        rec["current"],
        rec["command"],
        normal_force,
        controller.desired_normal_force.copy(),
        residual,
        hand_error,
        sim.position,
        sim.energy,
    )
