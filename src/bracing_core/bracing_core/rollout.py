"""The experiment without ROS: the same plant, simulator and controller the nodes run, stepped in
one process by the engine's closed-loop rollout (``bracing_engine.rollout``: law and simulator
in C++, no return to Python between steps), for tests, benchmarks, sweeps and studies.

    scenario = build_scenario("config/paper_4link.yaml", shared={"input_mode": "torque"})
    run = run_closed_loop(scenario, duration=10.0)
    run = run_recorded(build_scenario(...), duration=10.0)  # + everything a bag would hold (RunResult)

``shared`` overrides go to both nodes' parameters (the /** section of the file), ``sim``
and ``ctl`` to one of them; the step loop is the lockstep protocol of the nodes: the
controller answers state k, the simulator steps with that command held.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import bracing_engine as engine
from bracing_core import schema
from bracing_core.checks import configuration_warnings
from bracing_core.config import Plant, SimulatorConfig, build_simulator
from bracing_core.controller_config import ControllerConfig
from bracing_core.failures import Failure, History, diagnose, fed_back_contacts, succeeded
from bracing_core.law import DecoupledController
from bracing_core.link_penetration import LinkPenetration
from bracing_core.overrides import CONTROLLER, SIMULATOR, NodeOverrides, node_params
from bracing_core.simulator import Energy, Simulator
from bracing_core.watch import RunWatch

if TYPE_CHECKING:
    from bracing_core.schema.typed_values import ControllerValues, SimulatorValues

Overrides = Mapping[str, Any] | None


@dataclass
class Scenario:
    plant: Plant  # the simulator's plant
    sim: Simulator
    controller: DecoupledController | None  # built on its own plant, as in the node
    sim_config: SimulatorConfig | None = None  # what the simulator was built from (its divergence limit, ...)

    def sensors(self) -> engine.Sensors | None:
        """The configured sensors (fresh: the noise from its seed's start), None for the paper's exact ones."""
        config = self.sim_config
        if config is None or config.sensors.exact:
            return None
        return config.sensors.engine(config.step, self.plant.robot.prismatic.tolist())


def build_scenario(
    config: str | Path,
    shared: Overrides = None,
    sim: Overrides = None,
    ctl: Overrides = None,
    with_controller: bool = True,
) -> Scenario:
    search = [Path(config).resolve().parent]
    params = node_params(config, NodeOverrides(dict(shared or {}), dict(sim or {}), dict(ctl or {})))
    return build_scenario_from_params(params[SIMULATOR], params[CONTROLLER] if with_controller else None, search)


def build_scenario_from_params(
    sim_params: Mapping[str, Any], ctl_params: Mapping[str, Any] | None, search: list[Path] | None = None
) -> Scenario:
    """The scenario from each node's complete flat parameters (what a sweep worker receives)."""
    sim_values = schema.read("simulator", sim_params)
    ctl_values = schema.read("controller", ctl_params) if ctl_params is not None else None
    return build_scenario_from_values(sim_values, ctl_values, search)


def build_scenario_from_values(
    sim_values: schema.Values[SimulatorValues],
    ctl_values: schema.Values[ControllerValues] | None,
    search: list[Path] | None = None,
) -> Scenario:
    """The scenario from each node's typed values (``schema.read``; a run's plan holds them)."""
    sim_config = SimulatorConfig.from_values(sim_values, search or [])
    plant, simulator = build_simulator(sim_config)
    controller = None
    if ctl_values is not None:
        controller = DecoupledController(ControllerConfig.from_values(ctl_values, search or []))
        controller.check_task_rank(simulator.position)  # its own law's: one model built, not two
    return Scenario(plant, simulator, controller, sim_config)


def link_warnings(scenario: Scenario, times: np.ndarray, positions: np.ndarray) -> list[str]:
    """robot.collision_geometry: what the simulator node warns of its links over these recorded states (a link
    deeper than robot.penetration_tolerance inside a surface, once per link); none without it."""
    if scenario.sim_config is None or not scenario.sim_config.shared.collision_geometry:
        return []
    links = LinkPenetration(scenario.plant, scenario.sim.dynamics.engine)
    return [w for t, q in zip(times.tolist(), positions, strict=True) for w in links.measure(q, t)[1]]


@dataclass
class ClosedLoop:
    """A closed-loop run's arrays (``run_closed_loop``); row k is the state at the start of step k and what
    was sent/returned."""

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


def run_closed_loop(scenario: Scenario, duration: float) -> ClosedLoop:
    """The closed loop for ``duration`` seconds (rows: the N states stepped from)."""
    run = run_recorded(scenario, duration, divergence_checks=False)
    steps = run.time.size - 1
    return ClosedLoop(
        run.time[:steps],
        run.position[:steps],
        run.velocity[:steps],
        run.current[:steps],
        run.command[:steps],
        run.normal_force[:steps],
        run.desired_normal_force,
        run.residual[:steps],
        np.linalg.norm(run.hand_desired[:steps] - run.hand_actual[:steps], axis=1),
        scenario.sim.position,
        scenario.sim.energy,
    )


# The recorded arrays in the order an .npz holds them (RunResult.arrays).
RECORDED_ARRAYS = (
    "time", "position", "velocity", "current", "temperature", "command", "hand_desired", "hand_actual",
    "brace_desired", "brace_actual", "contact_position", "slip_velocity", "normal_force", "friction_force",
    "residual", "active", "desired_normal_force", "force_command", "measured_position", "measured_velocity",
    "energy_consumed", "energy_net", "copper_loss", "hand_orientation_error", "command_limit", "rolling_residual",
)  # fmt: skip


class RunResult(engine.Recording):
    """A closed-loop run (``run_recorded``): the engine's Recording, filled by its rollout (everything the
    nodes would publish in lockstep per state k = 0..N, N steps and the final state as in a bag: read-only
    views of the engine's memory, no copy), and what the run says beyond its numbers. A subclass, not a
    holder: ``run.position`` reads as the engine's, typed by its stubs.

    The arrays are the engine's: ``position`` (N+1, n) in model joint order (``joint_names``),
    ``brace_desired`` (N+1, b, 3) of the braced contacts (``braced_names``), ``contact_position`` (N+1, p, 3)
    of the simulator's contacts (``contact_names``), ``temperature`` with no columns where the thermal model
    does not apply, ``measured_position`` with no rows under exact sensors (``bracing_engine.Recording``).
    """

    def __init__(
        self,
        contact_names: tuple[str, ...],
        braced_names: tuple[str, ...],
        joint_names: tuple[str, ...],
        input_mode: str,
    ) -> None:
        super().__init__()
        self.contact_names = contact_names  # the simulator's contacts (obstacles and collision frames too)
        self.braced_names = braced_names  # the controller's: the contacts it keeps a force on
        self.joint_names = joint_names  # model order (the columns of position, ...)
        self.input_mode = input_mode
        self.warnings: tuple[str, ...] = ()  # the simulator's about the run (watch.RunWatch), as its node says them
        self.status = "ok"  # summary.json's: ok | failed (run_recorded's keep_failure)
        self.error: str | None = None  # what stopped the run, what ran away (failures.diagnose)
        self.hint: str | None = None  # what to change, for a known cause (failures)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every field as an array (for an .npz; the names as string arrays, no pickles)."""
        out = {name: getattr(self, name) for name in RECORDED_ARRAYS}
        out["contact_names"] = np.array(self.contact_names, dtype=str)
        out["braced_names"] = np.array(self.braced_names, dtype=str)
        out["joint_names"] = np.array(self.joint_names, dtype=str)
        out["input_mode"] = np.array(self.input_mode)
        return out


def run_recorded(
    scenario: Scenario, duration: float, divergence_checks: bool = True, keep_failure: bool = False
) -> RunResult:
    """The lockstep loop of the nodes, recording what they publish (the engine's rollout).

    Stops where the simulator node refuses to go on (``divergence_checks``, with the scenario's
    simulator configuration): DivergenceError for a non-finite state or force, a joint faster
    than ``divergence_speed`` or a held contact further than ``divergence_residual`` off its surface;
    with ``keep_failure`` the recording up to there instead, and the result's ``status``, ``error``
    and ``hint`` as bracing-pair's summary.json has them (``failures``), for a run that ends well too.
    The simulator's warnings about the run (``watch.RunWatch`` over the recorded states, as the node
    watches the states it reports) are the result's ``warnings`` (none without the scenario's
    simulator configuration).
    """
    sim, controller = scenario.sim, scenario.controller
    if controller is None:
        raise ValueError("run_recorded needs a scenario built with a controller")
    steps = round(duration / sim.step_size)
    config = scenario.sim_config if divergence_checks else None
    limits = (config.divergence_speed, config.divergence_residual) if config is not None else (np.inf, np.inf)
    watch = None
    if scenario.sim_config is not None:
        watch = RunWatch(scenario.plant, scenario.sim_config, sim, at_start=sim.steps_taken == 0)
    events = len(sim.events)
    plant = scenario.plant
    run = RunResult(
        tuple(plant.contact_set.names), tuple(controller.contact_set.names), tuple(plant.joint_names), plant.mode.value
    )
    # the commands saturated as the simulator node saturates them (motors.voltage_limit / torque_limit)
    sim.rollout(controller.engine, steps, *limits, scenario.sensors(), plant.command_limit, keep_failure=True, out=run)
    error = sim.rollout_error(run, *limits)
    if error is not None and not keep_failure:
        raise error
    warnings: list[str] = []
    if watch is not None:
        watch.events(sim.events[events:])
        warnings = watch.start()
        # the node says a link's warning as the state goes out, before the watch's on the states around it
        warnings += link_warnings(scenario, run.time, run.position)
        warnings += watch.states(run.time, run.active, run.normal_force, run.residual)
        warnings += [] if error is not None else watch.finish()
    run.warnings = tuple(warnings)
    if keep_failure:
        outcome = _outcome(scenario, run, error, warnings)
        run.status, run.error, run.hint = outcome.status, outcome.error, outcome.hint
    return run


def _outcome(scenario: Scenario, out: engine.Recording, error: Exception | None, warnings: list[str]) -> Failure:
    """status, error and hint of an in-process run, as bracing-pair's summary.json says them."""
    controller = scenario.controller
    assert controller is not None
    said = [*configuration_warnings(controller.config, controller.plant), *warnings]
    if error is None:
        return succeeded(said, fed_back_contacts(controller.config))
    history = History(out.time, out.position, out.velocity, scenario.plant.joint_names)
    step = (scenario.sim.step_size, scenario.sim.substeps)
    return diagnose(str(error), history, scenario.plant, controller.config, step, said)
