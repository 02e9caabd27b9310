"""The experiment without ROS: the same plant, simulator and controller cores the nodes run,
stepped in one process (tests, benchmarks, parameter sweeps).

    scenario = build_scenario("config/paper_4link.yaml", shared={"input_mode": "torque"})
    run = run_closed_loop(scenario, duration=10.0)
    recording = run_recorded(build_scenario(...), duration=10.0)  # + everything a bag would hold

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

from bracing_core.config import Plant, SimulatorConfig, build_simulator, check_step
from bracing_core.controller_config import ControllerConfig
from bracing_core.law import DecoupledController, check_task_rank
from bracing_core.params import load_params_file
from bracing_core.simulator import DivergenceError, Energy, Simulator

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
    sim_config: SimulatorConfig | None = None  # what the simulator was built from (its divergence limit, ...)


def build_scenario(
    config: str | Path,
    shared: Overrides = None,
    sim: Overrides = None,
    ctl: Overrides = None,
    with_controller: bool = True,
) -> Scenario:
    search = [Path(config).resolve().parent]
    return build_scenario_from_params(
        node_params(config, "bracing_simulator", shared, sim),
        node_params(config, "bracing_controller", shared, ctl) if with_controller else None,
        search,
    )


def build_scenario_from_params(
    sim_params: Mapping[str, Any], ctl_params: Mapping[str, Any] | None, search: list[Path] | None = None
) -> Scenario:
    """The scenario from each node's complete flat parameters (what a sweep worker receives)."""
    sim_config = SimulatorConfig.from_params(sim_params, search or [])
    plant, simulator = build_simulator(sim_config)
    controller = None
    if ctl_params is not None:
        controller_config = ControllerConfig.from_params(ctl_params, search or [])
        check_task_rank(controller_config, plant, simulator.position)
        controller = DecoupledController(controller_config)
    return Scenario(plant, simulator, controller, sim_config)


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


@dataclass
class Recording:
    """Everything the nodes would publish in lockstep, per state k = 0..N (N steps and the final
    state, as in a bag): the controller's answer to state k and the simulator's reports of step k
    (forces at its start under that answer, energies up to its start)."""

    time: np.ndarray  # (N+1,) [s]
    position: np.ndarray  # (N+1, n) [rad], model joint order
    velocity: np.ndarray  # (N+1, n) [rad/s]
    current: np.ndarray  # (N+1, n) [A]
    command: np.ndarray  # (N+1, n) [V] or [N m]
    hand_desired: np.ndarray  # (N+1, 3) [m]
    hand_actual: np.ndarray  # (N+1, 3) [m]
    brace_desired: np.ndarray  # (N+1, b, 3) [m], the b braced contacts (braced_names)
    brace_actual: np.ndarray  # (N+1, b, 3) [m]
    contact_position: np.ndarray  # (N+1, p, 3) [m], the simulator's p contact points (contact_names)
    slip_velocity: np.ndarray  # (N+1, p, 3) [m/s]
    normal_force: np.ndarray  # (N+1, p) [N]
    friction_force: np.ndarray  # (N+1, p) [N]
    residual: np.ndarray  # (N+1, p) [m]
    active: np.ndarray  # (N+1, p) bool
    desired_normal_force: np.ndarray  # (b,) [N]
    energy_consumed: np.ndarray  # (N+1,) [J]
    energy_net: np.ndarray  # (N+1,) [J]
    copper_loss: np.ndarray  # (N+1,) [J]
    contact_names: tuple[str, ...]  # the simulator's contacts (obstacles and collision frames too)
    braced_names: tuple[str, ...]  # the controller's: the contacts it keeps a force on
    joint_names: tuple[str, ...]  # model order (the columns of position, ...)
    input_mode: str

    def arrays(self) -> dict[str, np.ndarray]:
        """Every field as an array (for an .npz; the names as string arrays, no pickles)."""
        out = {name: value for name, value in vars(self).items() if isinstance(value, np.ndarray)}
        out["contact_names"] = np.array(self.contact_names, dtype=str)
        out["braced_names"] = np.array(self.braced_names, dtype=str)
        out["joint_names"] = np.array(self.joint_names, dtype=str)
        out["input_mode"] = np.array(self.input_mode)
        return out


def run_recorded(scenario: Scenario, duration: float) -> Recording:
    """The lockstep loop of the nodes, recording what they publish.

    Stops where the simulator node refuses to go on: DivergenceError for a non-finite state or
    force, a joint faster than ``divergence_speed`` or a held contact further than
    ``divergence_residual`` off its plane.
    """
    sim, controller = scenario.sim, scenario.controller
    if controller is None:
        raise ValueError("run_recorded needs a scenario built with a controller")
    steps = round(duration / sim.step_size)
    rows, n, p = steps + 1, sim.n, len(scenario.plant.contact_set)
    braced = len(controller.contact_set)
    joint = {key: np.zeros((rows, n)) for key in ("position", "velocity", "current", "command")}
    task = {key: np.zeros((rows, 3)) for key in ("hand_desired", "hand_actual")}
    brace = {key: np.zeros((rows, braced, 3)) for key in ("brace_desired", "brace_actual")}
    brace |= {key: np.zeros((rows, p, 3)) for key in ("contact_position", "slip_velocity")}
    contact = {key: np.zeros((rows, p)) for key in ("normal_force", "friction_force", "residual")}
    active = np.ones((rows, p), dtype=bool)
    energy = np.zeros((rows, 3))
    time = np.zeros(rows)
    for k in range(rows):
        time[k] = sim.time
        q, dq = sim.position, sim.velocity
        out = controller.update(sim.time, q, dq)
        joint["position"][k], joint["velocity"][k], joint["current"][k] = q, dq, sim.current
        joint["command"][k] = out.command
        task["hand_desired"][k], task["hand_actual"][k] = out.hand_desired, out.hand_actual
        brace["brace_desired"][k], brace["brace_actual"][k] = out.brace_desired, out.brace_actual
        e = sim.energy
        energy[k] = (e.consumed, e.net, e.copper_loss)
        # The final state gets its reports without a step, as the node's finish() does.
        d = sim.step(out.command) if k < steps else sim.evaluate(out.command)
        terms = d.contacts
        contact["normal_force"][k], contact["friction_force"][k] = d.normal_force, d.friction_force
        contact["residual"][k], brace["contact_position"][k] = terms.residual, terms.positions
        brace["slip_velocity"][k] = terms.slip_velocity
        if d.active is not None:
            active[k] = d.active
        if scenario.sim_config is not None:  # where the simulator node would refuse the step
            try:
                check_step(scenario.sim_config, d, sim.velocity)
            except DivergenceError as exc:
                raise DivergenceError(f"{exc} after the step at t = {time[k]:.3f} s") from None
    return Recording(
        time=time,
        **joint,
        **task,
        **brace,
        **contact,
        active=active,
        desired_normal_force=controller.desired_normal_force.copy(),
        energy_consumed=energy[:, 0],
        energy_net=energy[:, 1],
        copper_loss=energy[:, 2],
        contact_names=tuple(scenario.plant.contact_set.names),
        braced_names=tuple(controller.contact_set.names),
        joint_names=tuple(scenario.plant.joint_names),
        input_mode=scenario.plant.mode.value,
    )
