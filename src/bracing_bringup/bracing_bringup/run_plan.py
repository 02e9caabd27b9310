"""A run's plan: what bracing-pair and the launch file start, from the scenario file, ``--set`` and the
flags (``RunOptions``), checked against the schemas before any process starts: every node's parameters
(written to DIR/params.yaml), their typed values (read here: what the run's consumers take) and the
processes (``RunPlan``, ``plan_run``); the configurations' own checks (``check_configs``)."""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_core import rcl_yaml, schema
from bracing_core.overrides import CONTROLLER, SIMULATOR, node_params, with_layers
from bracing_core.params import resolve_file
from bracing_core.sensing import SensorConfig
from bracing_core.variants import variant_overrides

if TYPE_CHECKING:
    from bracing_core.schema.typed_values import ControllerValues, SimulatorValues

PARAMS_FILE = "params.yaml"
"""DIR/params.yaml: every parameter each node ran with (``bracing-simulator --ros-args --params-file``
runs it again)."""
MUJOCO = "mujoco"
MUJOCO_NEEDS = {"command_output": "effort_forward", "input_mode": "torque"}
"""--engine mujoco: the controller's torque law sent as a JointGroupEffortController takes it."""
PAIR_RECORD_BATCH = 100
"""States per record_batch the pair's nodes hand the recorder (``--set record_batch=0``: every topic
subscribed one by one, as any rosbag2 recorder does). The recorder's share of a lockstep step of the
paper arm fell from 31 % to 7.5 % (make bench: docs/results/performance.md)."""


@dataclass
class RunOptions:
    config: Path
    output: Path
    duration: float | None = None
    mode: str | None = None
    bracing: bool = True  # False: --no-bracing (no brace tasks; the surfaces stay, as obstacles)
    real_time: bool = False
    domain_id: int | None = None
    quiet: bool = False
    stall_timeout: float = 60.0  # [s] wall without sim progress before the run is declared hung
    parameters: dict[str, Any] = field(default_factory=dict)  # --set KEY=VALUE (flat names; see overrides)
    command_start: float | None = None  # wall time the run was asked for (default: run_pair's call)
    animation: bool = True  # draw animation.gif / .mp4 with the report
    show_timeline: bool = False  # print the timeline at the end (bracing-pair --timeline)
    free_space: bool = False  # --free-space: the surfaces removed (only watched), the paper's comparison
    network: bool = False  # --network: DDS sockets on every interface (default: loopback and shared memory)
    view: bool = False  # --view: bracing-view beside the nodes (a process of its own, best-effort subscriber)
    rrd: bool = False  # --rrd: DIR/run.rrd, the run for rerun's viewer, written from the bag
    engine: str = "bracing"  # --engine: bracing (our simulator) | mujoco (MuJoCo through ros2_control's topics)


def command_line(options: RunOptions) -> dict[str, Any]:
    """What the command line sets, as flat parameter names: ``--set``, then the flags (they win)."""
    given = dict(options.parameters)
    if options.mode is not None:
        given["input_mode"] = options.mode
    given.update(variant_overrides(options.bracing, options.free_space))
    if options.engine == MUJOCO:
        given.update(MUJOCO_NEEDS)
    return given


def pair_needs(options: RunOptions, urdf: Path, record_batch: int) -> dict[str, Any]:
    """What the pair sets over the scenario and the command line, as flat parameter names.

    Both nodes publish their first message only once the recorder has matched every topic they
    publish (with ``record_batch`` > 0: their batches, see bracing_ros.record_batch), and the
    simulator once the controller has too (joint_states: the controller, and the recorder when it
    subscribes to each topic; bracing-view subscribes once the run steps) and run_status has its
    subscribers: this process's watcher and the recorder (it keeps the run's warnings), and
    bracing-view's with --view (it is up before the nodes start; counting it makes sure the watcher
    is one of those matched). The nodes resolve a relative URDF from their working directory, so it
    is pinned to the file found now (``urdf``).
    """
    status_subscribers = 2 + int(options.view)
    needs: dict[str, Any] = {
        "wait_for_recorder": True,
        "min_subscribers": 1 if record_batch else 2,
        "min_status_subscribers": status_subscribers,
        "record_batch": record_batch,
    }
    if options.duration is not None:
        needs["duration"] = options.duration
    if options.real_time:
        needs["stepping"] = "real_time"
    needs["robot.urdf"] = str(urdf)
    return needs


def write_params(path: Path, node_params: dict[str, dict[str, Any]]) -> None:
    """The nodes' one params file, written so that rcl reads exactly these values back (every string
    quoted: a y stays an axis name, a float list stays floats; no aliases)."""
    path.write_text(rcl_yaml.dump({node: {"ros__parameters": params} for node, params in node_params.items()}))


@dataclass(frozen=True)
class RunProcess:
    """One process of a run: bracing-pair starts it as ``python -m module``, launch/pair.launch.py
    as ``package``'s ``executable``; both with these arguments (ours, then ROS's)."""

    name: str  # simulator | controller | recorder
    package: str
    executable: str
    module: str
    arguments: tuple[str, ...]
    ros_arguments: tuple[str, ...] = ()

    def argv(self) -> list[str]:
        ros = ["--ros-args", *self.ros_arguments] if self.ros_arguments else []
        return [sys.executable, "-m", self.module, *self.arguments, *ros]


@dataclass(frozen=True)
class RunPlan:
    """What a run starts, from (scenario file, --set overrides, flags), checked against the schemas
    (names, types, bounds): every node's parameters, typed and flat, and the processes. No file is written."""

    options: RunOptions
    sim_values: schema.Values[SimulatorValues]  # the simulator's typed parameters: what DIR/params.yaml gives it
    ctl_values: schema.Values[ControllerValues]  # the controller's
    node_params: dict[str, dict[str, Any]]  # each node's complete parameters (DIR/params.yaml)
    duration: float  # [s] of sim time
    expected_states: int  # lockstep: the states the recorder waits for before it closes the bag (0: any)

    @property
    def contacts(self) -> list[str]:
        return list(self.sim_values.contacts)

    @property
    def ground_truth(self) -> bool:
        """The simulator measures through sensors (sensors.*): it publishes the truth too, and the bag keeps it."""
        return not SensorConfig.from_values(self.sim_values).exact

    @property
    def search(self) -> list[Path]:
        return [self.options.config.parent]

    def processes(self, out: Path) -> list[RunProcess]:
        """The recorder, the controller and the simulator of a run into ``out`` (its params file
        ``out / PARAMS_FILE``, its bag ``out / "bag"``)."""
        params_file = str(out / PARAMS_FILE)
        recorder = ["--output", str(out / "bag"), "--contacts", ",".join(self.contacts)]
        recorder += ["--ground-truth"] if self.ground_truth else []
        recorder += ["--niceness", "10"]  # the lockstep loop comes first
        recorder += ["--drain-idle", "0.05"]  # stopped only after the nodes' last messages are acknowledged
        recorder += ["--params-file", params_file, "--scenario", self.options.config.stem]  # surfaces, name
        recorder += ["--from-batches"] if self.sim_values.params.record_batch else []
        if self.expected_states:
            recorder += ["--expect-states", str(self.expected_states)]  # it closes the bag once it has them all
        nodes = ("--params-file", params_file)
        if self.options.engine == MUJOCO:
            controller = (*nodes, "-p", "use_sim_time:=true")  # it follows MuJoCo's /clock
            mujoco_robot = ("bracing_mujoco", "bracing-mujoco-robot", "bracing_mujoco.mujoco_robot", (), nodes)
            return [
                RunProcess(
                    "recorder", "bracing_recorder", "bracing-recorder", "bracing_recorder.command", tuple(recorder)
                ),
                RunProcess(
                    "controller", "bracing_controller", "bracing-controller", "bracing_controller.node", (), controller
                ),
                RunProcess("simulator", *mujoco_robot),
            ]
        return [
            RunProcess("recorder", "bracing_recorder", "bracing-recorder", "bracing_recorder.command", tuple(recorder)),
            RunProcess("controller", "bracing_controller", "bracing-controller", "bracing_controller.node", (), nodes),
            RunProcess("simulator", "bracing_sim", "bracing-simulator", "bracing_sim.node", (), nodes),
        ]


def plan_run(options: RunOptions) -> RunPlan:
    """The one way a run's parameters are assembled for its nodes (bracing-pair, the launch file):
    the scenario file, then ``--set``, then the flags, then what the pair needs (``overrides``).
    The configurations' own checks (pinocchio's imports, ~0.25 s) are ``check_configs``'.
    Each node's typed values are read here, from the parameters its params file will hold; every
    consumer of the run (checks, diagnosis, bag notes, report) takes them from the plan."""
    search = [options.config.parent]
    given = node_params(options.config, command_line(options))  # the scenario file, parsed once
    # The scenario and the command line checked as given (refused here, before any process starts),
    # a value the pair overrides below too.
    sim = schema.read("simulator", given[SIMULATOR]).params
    schema.read("controller", given[CONTROLLER])
    urdf = resolve_file(sim.robot.urdf, "robot.urdf", search)
    duration = options.duration if options.duration is not None else float(sim.duration)
    step = float(sim.step)
    lockstep = sim.stepping == "lockstep" and not options.real_time and duration > 0
    lockstep = lockstep and options.engine != MUJOCO  # MuJoCo's robot promises no message count
    expected_states = round(duration / step) + 1 if lockstep else 0
    # Only --set changes it (a scenario file's record_batch is for its nodes started by hand, as its
    # wait_for_recorder). MuJoCo's robot publishes no batches: its recorder subscribes to each topic.
    record_batch = 0 if options.engine == MUJOCO else int(options.parameters.get("record_batch", PAIR_RECORD_BATCH))
    every = with_layers(given, pair_needs(options, urdf, record_batch))
    sim_values, ctl_values = schema.read("simulator", every[SIMULATOR]), schema.read("controller", every[CONTROLLER])
    return RunPlan(options, sim_values, ctl_values, every, duration, expected_states)


def check_configs(plan: RunPlan) -> list[str]:
    """The nodes' configurations built as an in-process run builds them (``rollout``: they would stop
    on the same error), the start posture's feasibility and the task's rank there: ConfigError,
    before the run leaves a bag behind. The targets out of the arm's reach: warnings, as the
    controller logs them (the summary's)."""
    from bracing_core.checks import reach_warnings
    from bracing_core.rollout import build_scenario_from_values

    scenario = build_scenario_from_values(plan.sim_values, plan.ctl_values, plan.search)
    assert scenario.controller is not None  # built with the controller's parameters
    return reach_warnings(scenario.controller.config, scenario.controller.plant)
