"""make bench: how fast the engine, the controller and the ROS pair are, measured side by side
in one run on this machine, with medians of repeats. Prints a table, writes bench/latest.json and (a full
run) the recorded file docs/results/data/bench.json, the same JSON, which the Performance page's tables are
rendered from (tools/docs_reference.py; bracing_experiments.recorded: its date, commit and machine).

- in process, alternately: the engine stepping the paper model (voltage input, RK4, 1 ms, elbow
  braced; the compiled step through its binding, its report as one array, as mj_step is timed in
  a Python loop) against MuJoCo stepping an equivalent MJCF (bench/mujoco_paper.py); the closed
  loop (law + engine, ``Simulator.rollout``: no return to Python between steps) on the paper model
  and on hyper_7link; the engine step alone on hyper_7link (a fixed command); ``Simulator.step``,
  the Python face the simulator node calls (the report as Python objects); the share of a step the links'
  distance queries take on ur5_table (robot.collision_geometry, the wrist at its link's surface);
- the ROS pair vs the DDS bound: bracing-pair in lockstep for 10 s of sim time, against the
  round trips/s of two rclpy processes ping-ponging messages of the same size over the
  nodes' own transport, times the step, measured before and after the pair (bench/dds_bound.py); and
  against the bound without Python: the same ping-pong between two C++ processes on rcl's C API
  (src/bracing_rcl_bench's rcl_pingpong);
  and the two nodes alone (no recorder), alternately with the pair: the recorder's share of a step (the
  wall time it adds; a difference of two runs on a shared machine, so it swings), and, steadier, the recorder
  process's CPU time per state while the pair steps over the recorded step (its log; every thread's);
- turnaround: the timeline of those pair runs (startup_s, stepping_s, shutdown_s, report_s,
  whole_run_s: see bracing_bringup.timeline), a `bracing-pair --duration 0.01` from command to
  exit, and `make run` against its runs' stepping time (the runs of bracing_bringup.paper_run);
- controller update latency (p50, p99); the controller node's whole callback on a state in the pair
  (p50, p99, p99.9, the maximum: its per-step work line);
- engine steps/s for generated chains of n links with p = 1 and 2 contacts, and the
  fitted growth exponent of cost with n.
- sweep throughput: in-process runs per minute with 1 and 2 local worker processes and a
  Dask LocalCluster, and the parallel efficiency (bench/sweep_bench.py);
- optimiser throughput: bracing-optimize's trials per minute on the paper arm (2 local workers).

``--quick`` cuts every figure to about a second or less (runs of 0.01 s of sim time, few
steps, one repeat): it checks that every key is produced (``make test`` runs it,
test/test_bench.py), its numbers are not measurements. Without ``mujoco`` (requirements.lock,
which the set-up installs) a quick run writes the MuJoCo keys as null and says why; a full run
stops.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bracing_experiments.recorded import machine, write_recorded

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PAPER = ROOT / "config" / "paper_4link.yaml"
HYPER = ROOT / "config" / "hyper_7link.yaml"
UR5 = ROOT / "config" / "ur5_table.yaml"
RECORD = ROOT / "docs" / "results" / "data" / "bench.json"
TINY_RUN_S = 0.01  # the sim time of the turnaround's `bracing-pair --duration 0.01`
sys.path.insert(0, str(HERE))

_scratch_root: Path | None = None  # main's temporary directory: every run's files, removed at the end


def scratch(prefix: str) -> Path:
    """A new directory for one measurement's files (under main's temporary directory)."""
    return Path(tempfile.mkdtemp(prefix=prefix, dir=_scratch_root))


def _median_rate(run_once: Any, repeats: int) -> tuple[float, list[float]]:
    samples = [run_once() for _ in range(repeats)]
    return statistics.median(samples), samples


def engine_steps_per_s(steps: int = 3000, repeats: int = 5, scenario: Any = None) -> tuple[float, list[float]]:
    from bracing_core.rollout import build_scenario

    def once() -> float:
        sim = (scenario() if scenario else build_scenario(PAPER, with_controller=False)).sim
        command = np.full(sim.n, 1.0)
        # The compiled step through its binding, its report as the engine's answer: the analogue of
        # mj_step in a Python loop (Simulator.step, which also builds the report's Python objects, is
        # simulator_step_us).
        step = sim.engine.step
        for _ in range(50):  # warm-up
            step(command)
        start = time.perf_counter()
        for _ in range(steps):
            step(command)
        return steps / (time.perf_counter() - start)

    return _median_rate(once, repeats)


def engine_step_us(config: Path, steps: int = 3000, segment: int = 500, python_face: bool = False) -> float:
    """Microseconds per step of ``config``'s simulator (no controller), 1.0 V held on every joint:
    the compiled step through its binding (``python_face``: ``Simulator.step``, with the report's
    Python objects); from the initial state again every ``segment`` steps, outside the clock, so
    every timed step has the scenario's contacts as they start (hyper_7link: both elbows braced,
    no obstacle touched; 500 steps of 1 V keep it so)."""
    from bracing_core.rollout import build_scenario

    sim = build_scenario(config, with_controller=False).sim
    command = np.full(sim.n, 1.0)
    step = sim.step if python_face else sim.engine.step
    start = sim.checkpoint()
    for _ in range(50):  # warm-up
        step(command)
    elapsed, done = 0.0, 0
    while done < steps:
        sim.restore(start)
        count = min(segment, steps - done)
        begin = time.perf_counter()
        for _ in range(count):
            step(command)
        elapsed += time.perf_counter() - begin
        done += count
    return 1e6 * elapsed / steps


def collision_share_of_step(steps: int = 2000, repeats: int = 5) -> dict[str, Any]:
    """The share of a simulator step the links' distance queries take on the shipped real arm (ur5_table.yaml,
    torque input, a fixed command): the wrist braced at its link's surface (point: geometry, its point found by
    coal at every evaluation) and every link's shapes measured against the table once per state
    (robot.collision_geometry: the engine's ``measure_links``), against the same steps braced at the frame with
    nothing measured, alternately in one run: share = 1 - frame step / (geometry step + measurement). Also the
    simulator's bookkeeping of the measurement per state in Python (``LinkPenetration.measure``: the deepest link
    per surface, each link's deepest, the warnings), which is reporting, not queries."""
    from bracing_core.link_penetration import LinkPenetration
    from bracing_core.rollout import build_scenario

    geometry = {"robot.collision_geometry": True, "contacts.wrist.point": "geometry", "contacts.wrist.offset": 0.19}
    samples: dict[str, list[float]] = {"frame": [], "geometry": [], "bookkeeping": []}

    def per_step_us(shared: dict[str, Any]) -> None:
        scenario = build_scenario(UR5, shared={"input_mode": "torque", **shared}, with_controller=False)
        sim = scenario.sim
        watch = LinkPenetration(scenario.plant, sim.dynamics.engine) if shared else None
        command = np.zeros(sim.n)
        step, start = sim.engine.step, sim.checkpoint()
        for _ in range(20):  # warm-up
            step(command)
        sim.restore(start)
        begin = time.perf_counter()
        if watch is None:
            for _ in range(steps):
                step(command)
            samples["frame"].append(1e6 * (time.perf_counter() - begin) / steps)
            return
        measure, surfaces, engine = sim.dynamics.engine.measure_links, watch.surfaces, sim.engine
        for _ in range(steps):
            step(command)
            measure(engine.position, surfaces)
        samples["geometry"].append(1e6 * (time.perf_counter() - begin) / steps)
        q = sim.position
        begin = time.perf_counter()
        for _ in range(steps):
            watch.measure(q, 0.0)
        samples["bookkeeping"].append(1e6 * (time.perf_counter() - begin) / steps)

    for _ in range(repeats):  # alternating: a drift of the machine's speed hits both alike
        per_step_us({})
        per_step_us(geometry)
    frame, measured = statistics.median(samples["frame"]), statistics.median(samples["geometry"])
    return {
        "share": 1.0 - frame / measured,
        "frame_step_us": frame,
        "geometry_step_us": measured,
        "bookkeeping_us": statistics.median(samples["bookkeeping"]),
        "samples_us": samples,
    }


def rollout_steps_per_s(config: Path, duration: float = 10.0) -> float:
    """Closed-loop steps/s of ``config``'s scenario (the controller's law and the simulator) for
    ``duration`` seconds of sim time from its start, in the engine's rollout
    (``Simulator.rollout``, as the in-process runs of ``bracing_core.rollout`` step it, with the
    simulator node's divergence checks). Building the scenario is not timed."""
    from bracing_core.rollout import build_scenario

    scenario = build_scenario(config)
    sim, controller, sim_config = scenario.sim, scenario.controller, scenario.sim_config
    assert controller is not None and sim_config is not None
    steps = round(duration / sim.step_size)
    start = time.perf_counter()
    sim.rollout(controller.engine, steps, sim_config.divergence_speed, sim_config.divergence_residual)
    return steps / (time.perf_counter() - start)


def controller_latency_us(updates: int = 3000) -> dict[str, float]:
    from bracing_core.rollout import build_scenario

    scenario = build_scenario(PAPER)
    sim, controller = scenario.sim, scenario.controller
    assert controller is not None
    samples = np.zeros(updates)
    for k in range(updates):
        q, dq, t = sim.position, sim.velocity, sim.time
        start = time.perf_counter()
        out = controller.update(t, q, dq)
        samples[k] = (time.perf_counter() - start) * 1e6
        sim.step(out.command)
    return {
        "p50": float(np.percentile(samples, 50)),
        "p99": float(np.percentile(samples, 99)),
        "mean": float(samples.mean()),
    }


def chain_scenario(n: int, p: int) -> Any:
    """An n-link chain of the paper's links with p contacts on horizontal planes through the
    contact frames' start positions (feasible by construction)."""
    from bracing_core.chain_urdf import chain_urdf
    from bracing_core.config import SimulatorConfig, build_simulator

    links = [max(1, (n * (j + 1)) // (2 * p)) for j in range(p)] if p else []
    urdf = scratch("bench_chain_") / f"chain{n}.urdf"
    urdf.write_text(
        chain_urdf(
            f"chain{n}", [1.0] * n, [0.5] * n, [0.03] * n, [2.0] * n, {f"c{j}": link for j, link in enumerate(links)}
        )
    )
    rng = np.random.default_rng(n)
    q0 = rng.uniform(-0.6, 0.6, n).tolist()
    params: dict[str, Any] = {
        "robot.urdf": str(urdf),
        "robot.joint_names": [f"joint{k + 1}" for k in range(n)],
        "input_mode": "voltage",
        "initial_position": q0,
        **{
            f"motors.{f}": [v] * n
            for f, v in (
                ("torque_constant", 0.2),
                ("resistance", 0.6),
                ("inductance", 0.17),
                ("rotor_inertia", 0.000164),
                ("gear_ratio", 3.0),
                ("gear_damping", 0.1),
            )
        },
        "contacts.names": [f"c{j}" for j in range(p)],
    }
    for j in range(p):
        params[f"contacts.c{j}.frame"] = f"c{j}"
        params[f"contacts.c{j}.friction"] = 0.1
        params[f"contacts.c{j}.offset"] = 0.0
    # Put each plane through its frame's start position.
    from bracing_core.model import RobotModel

    robot = RobotModel.from_urdf(urdf)
    robot.compute(np.array(q0), np.zeros(n))
    for j in range(p):
        params[f"contacts.c{j}.offset"] = float(robot.frame_position(robot.frame_id(f"c{j}"))[2])

    def build() -> Any:
        from bracing_core.rollout import Scenario

        plant, sim = build_simulator(SimulatorConfig.from_params(params))
        return Scenario(plant, sim, None)

    return build


def scaling(repeats: int = 3, steps: int = 1000) -> dict[str, Any]:
    results: dict[str, Any] = {}
    sizes = (4, 8, 16, 32)
    samples: dict[tuple[int, int], list[float]] = {(p, n): [] for p in (1, 2) for n in sizes}
    for _ in range(repeats):  # every size once per round: a drift of the machine's speed hits all alike
        for p, n in samples:
            samples[p, n] += engine_steps_per_s(steps=steps, repeats=1, scenario=chain_scenario(n, p))[1]
    for p in (1, 2):
        rates = {n: statistics.median(samples[p, n]) for n in sizes}
        ns = np.array(list(rates))
        cost = 1.0 / np.array(list(rates.values()))
        exponent = float(np.polyfit(np.log(ns), np.log(cost), 1)[0])
        results[f"p{p}"] = {"steps_per_s": {str(k): v for k, v in rates.items()}, "cost_exponent": exponent}
    return results


def pair_run(duration: float, *extra: str) -> dict[str, Any]:
    """One bracing-pair run in lockstep, as a user starts it: its timeline (``DIR/timeline.json``:
    startup, stepping, shutdown, report, whole run), the wall time of the command from start to
    exit, and the stepping real-time factor (sim time over the wall time from the first step to
    the last), and the share of a core the recorder process took while the pair stepped (``recorder_cpu_share``:
    its log's ``STEPPING_CPU_LINE``; its CPU time per state over a step) and that CPU time per state [us]."""
    from bracing_recorder.command import STEPPING_CPU_LINE

    out = scratch("bench_pair_") / "run"
    argv = [sys.executable, "-m", "bracing_bringup.pair", "--config", str(PAPER), "--duration", str(duration)]
    argv += ["--output", str(out), "--quiet", *extra]  # the pair holds a free domain id of its own
    start = time.monotonic()
    done = subprocess.run(argv, capture_output=True, text=True, timeout=1800)
    command_s = time.monotonic() - start
    if done.returncode != 0:
        raise RuntimeError(f"bracing-pair failed: {done.stderr[-2000:]}")
    timeline = json.loads((out / "timeline.json").read_text())
    phases = {key: timeline[key] for key in ("startup_s", "stepping_s", "shutdown_s", "report_s", "whole_run_s")}
    found = re.search(re.escape(STEPPING_CPU_LINE) + r": ([0-9.]+)%", (out / "logs" / "recorder.log").read_text())
    if found is None:
        raise RuntimeError(f"no '{STEPPING_CPU_LINE}' line in the recorder's log ({out / 'logs'})")
    cpu_share = float(found[1]) / 100.0  # of a core while the pair stepped: its CPU time per state over a step
    return {
        "recorder_cpu_us_per_state": cpu_share * phases["stepping_s"] / duration * 1e3,
        "recorder_cpu_share": cpu_share,
        **phases,
        "command_s": command_s,
        "stepping_real_time_factor": duration / phases["stepping_s"],
        "last_step_to_last_file_s": phases["shutdown_s"] + phases["report_s"],
        "events": timeline["events"],
    }


def pair_without_recorder(duration: float = 10.0) -> dict[str, Any]:
    """The two nodes alone in lockstep (no recorder: the simulator waits for the controller only):
    the stepping real-time factor, measured as in ``pair_run`` (side by side with the pair, it gives
    the recorder's share of a step), and each node's per-step work from its log (step_timing)."""
    from bracing_bringup.domains import hold_domain
    from bracing_core.step_timing import read_work_line
    from bracing_ros.status import Status, StatusWatcher

    out = scratch("bench_nodes_")
    overrides = out / "overrides.yaml"
    urdf = str(PAPER.parent / "paper_4link.urdf")
    # min_status_subscribers: the watcher below hears "finished" (a 0.01 s run can end before it matched)
    sim = {
        "duration": duration,
        "min_subscribers": 1,
        "min_status_subscribers": 1,
        "wait_for_recorder": False,
        "robot.urdf": urdf,
    }
    controller = {"wait_for_recorder": False, "robot.urdf": urdf}
    overrides.write_text(
        json.dumps(
            {"bracing_simulator": {"ros__parameters": sim}, "bracing_controller": {"ros__parameters": controller}}
        )
    )
    args = ["--ros-args", "--params-file", str(PAPER), "--params-file", str(overrides)]
    with hold_domain(None) as domain:
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain.domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        simulator: dict[str, float] = {}  # its run_status events: wall time of the first of each

        def on_status(status: Status) -> None:
            if status.node == "bracing_simulator":
                simulator.setdefault(status.event, status.wall_time_s)

        watcher = StatusWatcher(domain.domain_id, on_status, env).start()
        with (out / "controller.log").open("wb") as clog, (out / "simulator.log").open("wb") as slog:
            controller_proc = subprocess.Popen(
                [sys.executable, "-m", "bracing_controller.node", *args], stdout=clog, stderr=subprocess.STDOUT, env=env
            )
            try:
                code = subprocess.run(
                    [sys.executable, "-m", "bracing_sim.node", *args],
                    stdout=slog,
                    stderr=subprocess.STDOUT,
                    env=env,
                    timeout=1800,
                ).returncode
            finally:
                controller_proc.send_signal(signal.SIGINT)
                try:
                    controller_proc.wait(30)
                except subprocess.TimeoutExpired:  # never leave it running in a domain another run may take
                    controller_proc.kill()
                    controller_proc.wait()
                watcher.stop()
    if code != 0:
        raise RuntimeError(f"the simulator failed: {(out / 'simulator.log').read_text()[-2000:]}")
    work = {name: read_work_line((out / f"{name}.log").read_text()) for name in ("simulator", "controller")}
    missing = [name for name, line in work.items() if line is None]
    if missing:
        raise RuntimeError(f"no per-step work line in the {' and '.join(missing)} log ({out})")
    if not {"stepping", "finished"} <= simulator.keys():
        raise RuntimeError(f"run_status did not say both stepping and finished (heard {sorted(simulator)}; {out})")
    return {"real_time_factor": duration / (simulator["finished"] - simulator["stepping"]), "work": work}


def controller_callback_us(bare_runs: list[dict[str, Any]]) -> dict[str, float]:
    """The controller node's per-state work in the bare pair [us] (step_timing: decoding, checks, the law, the
    two messages out): the medians over the runs of its p50, p99 and p99.9 and of its p50 until the command
    is out (out_p50); max, the longest of every run."""
    works = [run["work"]["controller"] for run in bare_runs]
    callback = {key: statistics.median(w[key] for w in works) for key in ("p50", "p99", "p99_9", "out_p50")}
    callback["max"] = max(w["max"] for w in works)
    return callback


def step_breakdown_us(
    pair_rtf: float, bare: list[dict[str, Any]], engine_us: float, law_us: float, bound_round_trip_us: float
) -> dict[str, float]:
    """Where a lockstep step's wall time goes [us per 1 ms step], along the loop's critical path: the
    simulator's work from the controller's answer taken to the next state out, the controller's work
    from that state taken to its command out (each from the node's own log, the bare runs' medians)
    less the engine's and the law's in-process cost; the rest of the bare step (DDS both ways and the
    wake-ups, and the CPU the nodes' work after their answer takes meanwhile on two cores); what the
    recorder adds (the recorded pair against the bare one). Those parts add up to ``step``. Beside
    them: each node's work after its answer is out (the simulator's reports, the controller's
    controller_state: overlapping the other node), each node's time in rclpy's publish per step
    (the DDS writes, inside its work) and the DDS bound's round trip."""
    bare_step = 1e3 / statistics.median(run["real_time_factor"] for run in bare)
    sim_to_state = statistics.median(run["work"]["simulator"]["out_mean"] for run in bare)
    sim_work = statistics.median(run["work"]["simulator"]["mean"] for run in bare)
    ctl_to_command = statistics.median(run["work"]["controller"]["out_mean"] for run in bare)
    ctl_work = statistics.median(run["work"]["controller"]["mean"] for run in bare)
    step = 1e3 / pair_rtf
    return {
        "step": step,
        "simulator_node": sim_to_state - engine_us,
        "engine": engine_us,
        "controller_node": ctl_to_command - law_us,
        "law": law_us,
        "dds_round_trip": bare_step - sim_to_state - ctl_to_command,
        "recorder": step - bare_step,
        "simulator_reports_overlapped": sim_work - sim_to_state,  # not a part of the sum
        "controller_state_overlapped": ctl_work - ctl_to_command,  # nor this
        # of the nodes' parts: their time in rclpy's publish (the DDS writes, the peer's wake-up among them)
        "simulator_dds_writes": statistics.median(run["work"]["simulator"].get("writes_mean", 0.0) for run in bare),
        "controller_dds_writes": statistics.median(run["work"]["controller"].get("writes_mean", 0.0) for run in bare),
        "dds_bound_round_trip": bound_round_trip_us,  # for comparison: not a part of the sum
    }


def bare_import_s(repeats: int = 3) -> float:
    """A fresh interpreter's ``import rclpy, pinocchio`` [s], command to exit (median): what any node
    process pays before its own code, the floor of a run's turnaround."""
    samples = []
    for _ in range(repeats):
        start = time.monotonic()
        subprocess.run([sys.executable, "-c", "import rclpy, pinocchio"], check=True)
        samples.append(time.monotonic() - start)
    return statistics.median(samples)


def target_figures(result: dict[str, Any], sweep: dict[str, Any]) -> dict[str, float | None]:
    """The speed figures with targets (``TARGETS``), as ratios of figures of this one run."""
    works = [work["controller"] for work in result["node_work_us"]]
    law_us = result["controller_update_us_p50"]
    rollout_s = result["rollout_sim_time_s"] * 1000.0 / result["rollout_steps_per_s"]  # one rollout [s]
    same_runs = sweep["run_sim_time_s"] == result["rollout_sim_time_s"]
    return {
        "pair_vs_bound": result["pair_vs_bound"],
        "pair_vs_no_recorder": result["pair_real_time_factor"] / result["pair_real_time_factor_no_recorder"],
        "recorder_share_of_step": result["recorder_share_of_step"],
        "recorder_cpu_share_of_step": result["recorder_cpu_share_of_step"],
        "controller_callback_p50_vs_law": statistics.median(w["p50"] for w in works) / law_us,
        "controller_callback_p99_vs_law": statistics.median(w["p99"] for w in works) / law_us,
        "engine_vs_mujoco": result["engine_vs_mujoco"],
        "sweep_row_vs_rollout": sweep["mean_run_s"]["local_1"] / rollout_s if same_runs else None,
        "make_run_vs_stepping": result["make_run_vs_stepping"],
        "run_wall_minus_stepping_s": result["whole_run_s"] - result["stepping_s"],
        "tiny_run_vs_bare_import": result["tiny_run_command_s"] / result["bare_import_s"],
    }


TARGETS = {
    "pair_vs_bound": ">= 0.6",
    "pair_vs_no_recorder": ">= 0.9",
    "recorder_share_of_step": "<= 0.10",
    "recorder_cpu_share_of_step": "<= 0.10",
    "controller_callback_p50_vs_law": "<= 1.5",
    "controller_callback_p99_vs_law": "<= 3",
    "engine_vs_mujoco": ">= 2",
    "sweep_row_vs_rollout": "<= 1.3",
    "make_run_vs_stepping": "<= 1.25",
    "run_wall_minus_stepping_s": "<= 2.0",
    "tiny_run_vs_bare_import": "<= 3",
}
"""The targets on ``target_figures`` (printed beside them; a figure, never a timed test)."""


def make_run(duration: float | None = None) -> dict[str, Any]:
    """``make run``'s command (bracing_bringup.paper_run: its runs, the table, the comparison) from
    command to exit, against the sum of its runs' stepping time (each run's timeline.json).
    ``duration``: the runs' sim time (``--duration``; None: the scenario's, as ``make run``)."""
    from bracing_bringup.paper_run import RUNS

    out = scratch("bench_make_run_")
    argv = [sys.executable, "-m", "bracing_bringup.paper_run", "--output", str(out)]
    argv += [] if duration is None else ["--duration", str(duration)]
    start = time.monotonic()
    done = subprocess.run(argv, capture_output=True, text=True, timeout=1800, cwd=ROOT)
    total = time.monotonic() - start
    if done.returncode != 0:
        raise RuntimeError(f"make run failed: {done.stderr[-2000:]}")
    timelines = [json.loads((out / run.name / "timeline.json").read_text()) for run in RUNS]
    stepping = sum(timeline["stepping_s"] for timeline in timelines)
    return {"whole_s": total, "stepping_s": stepping, "ratio": total / stepping, "runs": [run.name for run in RUNS]}


def optimize_trials_per_min(trials: int = 40, duration: float = 10.0) -> float:
    """bracing-optimize's throughput: trials per minute of the paper arm's problem (energy
    subject to hand RMS <= 30 mm over f_nd and the brace target's y), 2 local workers, warmed up first
    (the search alone: no reference runs, a fresh study)."""
    from bracing_experiments.executors import make_executor
    from bracing_experiments.optimize_search import open_study, search
    from bracing_experiments.optimize_specs import build_problem

    problem = build_problem(
        PAPER,
        ["contacts.elbow.desired_normal_force=0:40", "contacts.elbow.target[1]=0.35:0.85"],
        ["energy_consumed_j"],
        ["hand_rms_error_m<=0.03"],
        duration,
    )
    with make_executor(2) as executor:
        search(problem, open_study(problem, scratch("bench_optimize_warm_")), executor, 2, progress=False)
        result = search(problem, open_study(problem, scratch("bench_optimize_")), executor, trials, progress=False)
    return 60.0 * result.ran / result.wall_time_s


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--output", type=Path, default=HERE / "latest.json")
    parser.add_argument(
        "--record",
        type=Path,
        default=None,
        help=f"the recorded file for the docs (default, a full run: {RECORD.relative_to(ROOT)}; quick: none)",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="every figure for about a second or less: checks that every key is produced, not the speed",
    )
    args = parser.parse_args(argv)
    try:
        from mujoco_paper import mujoco_steps_per_s
    except ImportError as exc:  # requirements.lock's (an environment set up before it)
        if not args.quick:
            print(f"error: {exc}: pip install -r requirements.lock (make setup does)", file=sys.stderr)
            return 2
        mujoco_steps_per_s = None
        mujoco_missing: str | None = f"mujoco not installed ({exc}): the MuJoCo keys are null"
        print(f"note: {mujoco_missing}", flush=True)
    else:
        mujoco_missing = None
    global _scratch_root
    with tempfile.TemporaryDirectory(prefix="bench_") as work:
        _scratch_root = Path(work)
        try:
            result, rows = _measure(args.quick, mujoco_steps_per_s)
        finally:
            _scratch_root = None
    result["mujoco_missing"] = mujoco_missing
    result["machine"] = machine()
    write_recorded(args.output, result, ROOT)
    record = args.record if args.record is not None or args.quick else RECORD
    if record is not None:
        write_recorded(record, result, ROOT)
        print(f"recorded for the docs: {record} (python tools/docs_reference.py renders its tables)")
    width = max(len(r[0]) for r in rows)
    for label, value in rows:
        print(f"{label:<{width}}  {value}")
    if args.quick:
        print("quick mode: every key produced; the numbers are not measurements")
    print(f"written to {args.output}")
    return 0


def _measure(quick: bool, mujoco_steps_per_s: Any) -> tuple[dict[str, Any], list[tuple[str, str]]]:
    """Every figure, side by side; the keys of bench/latest.json and the rows of the table."""
    from dds_bound import dds_round_trips_per_s
    from sweep_bench import sweep_throughput

    started = time.monotonic()
    repeats = 1 if quick else 5
    engine_steps, mujoco_steps, rollout_s = (300, 1000, 1.0) if quick else (3000, 10000, 10.0)
    print("in process, alternately: engine, MuJoCo, closed-loop rollouts, hyper_7link's step ...", flush=True)
    engine_samples: list[float] = []
    mujoco_samples: list[float] = []
    rollout_samples: list[float] = []
    rollout_hyper_samples: list[float] = []
    hyper_step_samples: list[float] = []
    python_step_samples: list[float] = []
    for _ in range(repeats):  # alternating: a drift of the machine's speed hits all alike
        engine_samples += engine_steps_per_s(steps=engine_steps, repeats=1)[1]
        if mujoco_steps_per_s is not None:
            mujoco_samples += mujoco_steps_per_s(n_steps=mujoco_steps, repeats=1)["samples"]
        rollout_samples.append(rollout_steps_per_s(PAPER, rollout_s))
        rollout_hyper_samples.append(rollout_steps_per_s(HYPER, rollout_s))
        hyper_step_samples.append(engine_step_us(HYPER, engine_steps))
        python_step_samples.append(engine_step_us(PAPER, engine_steps, python_face=True))
    engine = statistics.median(engine_samples)
    mujoco = statistics.median(mujoco_samples) if mujoco_samples else None
    rollout = statistics.median(rollout_samples)
    rollout_hyper = statistics.median(rollout_hyper_samples)
    hyper_step = statistics.median(hyper_step_samples)
    print("the links' distance queries' share of a step (ur5_table, robot.collision_geometry) ...", flush=True)
    collision = collision_share_of_step(*((200, 1) if quick else (2000, 5)))
    print("controller ...", flush=True)
    latency = controller_latency_us(300 if quick else 3000)
    # The bound is measured right before and right after the pair and averaged: this machine's
    # speed drifts over minutes, and the ratio must compare like with like.
    step = 0.001
    bound_runs: list[dict[str, Any]] = []
    objects_runs: list[dict[str, Any]] = []
    rcl_runs: list[dict[str, Any]] = []
    dds = {"n": 200, "repeats": 1, "warmup": 50} if quick else {"n": 2000, "repeats": 3}

    def measure_bounds(label: str) -> None:
        print(label, flush=True)
        bound_runs.append(dds_round_trips_per_s(**dds, wire="cdr"))
        objects_runs.append(dds_round_trips_per_s(**dds, wire="objects"))
        rcl_runs.append(dds_round_trips_per_s(**dds, wire="rcl"))

    measure_bounds("dds bound ...")
    duration = TINY_RUN_S if quick else 10.0
    print(f"pair ({duration:g} s of sim time), with and without the recorder, alternately ...", flush=True)
    pair_runs: list[dict[str, Any]] = []
    bare_runs: list[dict[str, Any]] = []
    for _ in range(1 if quick else 3):  # 2 rounds gave the recorder's share as 7.5 % and 15.8 % on like code
        pair_runs.append(pair_run(duration))
        bare_runs.append(pair_without_recorder(duration))
    measure_bounds("dds bound again ...")
    print(f"turnaround: bracing-pair --duration {TINY_RUN_S:g}, and make run ...", flush=True)
    # Quick: the pair runs above are already `bracing-pair --duration 0.01` runs.
    tiny = pair_runs if quick else [pair_run(TINY_RUN_S) for _ in range(2)]
    paper = make_run(TINY_RUN_S if quick else None)
    pair = {key: statistics.median(run[key] for run in pair_runs) for key in pair_runs[0] if key != "events"}
    pair["stepping"] = pair["stepping_real_time_factor"]
    pair["whole_run"] = duration / pair["whole_run_s"]
    without_recorder = statistics.median(run["real_time_factor"] for run in bare_runs)
    # Per 1 ms step: wall time with the recorder vs without it.
    recorder_share = 1.0 - pair["stepping"] / without_recorder
    tiny_command = statistics.median(run["command_s"] for run in tiny)
    bare_import = bare_import_s(1 if quick else 3)
    print("scaling ...", flush=True)
    scale = scaling(repeats=1, steps=200) if quick else scaling(repeats=3)
    print("sweep throughput (1 and 2 local workers, Dask LocalCluster) ...", flush=True)
    sweep = sweep_throughput(2, 0.1, 1) if quick else sweep_throughput()
    print("optimiser throughput (2 local workers) ...", flush=True)
    # Quick: the shortest runs whose hand RMS (t >= 2 s, the constraint) has a sample; shorter ones are refused.
    optimize_rate = optimize_trials_per_min(4, 2.01) if quick else optimize_trials_per_min()
    bound = statistics.mean(run["round_trips_per_s"] for run in bound_runs) * step
    bound_objects = statistics.mean(run["round_trips_per_s"] for run in objects_runs) * step
    bound_rcl = statistics.mean(run["round_trips_per_s"] for run in rcl_runs) * step
    callback = controller_callback_us(bare_runs)
    breakdown = step_breakdown_us(pair["stepping"], bare_runs, 1e6 / engine, latency["mean"], 1e3 / bound)
    result = {
        "quick": quick,
        "engine_steps_per_s": engine,
        "engine_samples": engine_samples,
        "mujoco_steps_per_s": mujoco,
        "mujoco_samples": mujoco_samples if mujoco_samples else None,
        "engine_vs_mujoco": engine / mujoco if mujoco else None,
        "rollout_steps_per_s": rollout,
        "rollout_samples": rollout_samples,
        "rollout_hyper_7link_steps_per_s": rollout_hyper,
        "rollout_hyper_7link_samples": rollout_hyper_samples,
        "rollout_sim_time_s": rollout_s,
        "engine_hyper_7link_step_us": hyper_step,
        "engine_hyper_7link_step_us_samples": hyper_step_samples,
        "simulator_step_us": statistics.median(python_step_samples),  # the Python face, paper model
        "simulator_step_us_samples": python_step_samples,
        "collision_share_of_step": collision["share"],
        "collision_step_us": collision,
        "pair_real_time_factor": pair["stepping"],
        "pair_real_time_factor_whole_run": pair["whole_run"],
        "pair_real_time_factor_no_recorder": without_recorder,
        "recorder_share_of_step": recorder_share,
        "recorder_cpu_us_per_state": pair["recorder_cpu_us_per_state"],
        "recorder_cpu_share_of_step": pair["recorder_cpu_share"],
        "pair_sim_time_s": duration,
        "startup_s": pair["startup_s"],
        "stepping_s": pair["stepping_s"],
        "shutdown_s": pair["shutdown_s"],
        "report_s": pair["report_s"],
        "whole_run_s": pair["whole_run_s"],
        "last_step_to_last_file_s": pair["last_step_to_last_file_s"],
        "timeline_events": pair_runs[0]["events"],
        "tiny_run_command_s": tiny_command,
        "tiny_run_timeline": {key: value for key, value in tiny[0].items() if key != "events"},
        "bare_import_s": bare_import,
        "make_run_s": paper["whole_s"],
        "make_run_stepping_s": paper["stepping_s"],
        "make_run_vs_stepping": paper["ratio"],
        "make_run_runs": paper["runs"],
        "dds_bound_real_time_factor": bound,
        "dds_round_trip_us": 1e3 / bound,
        "dds_bound_before_after": [run["round_trips_per_s"] * step for run in bound_runs],
        "pair_vs_bound": pair["stepping"] / bound,
        "dds_bound_objects_real_time_factor": bound_objects,
        "pair_vs_objects_bound": pair["stepping"] / bound_objects,
        "dds_bound_objects_before_after": [run["round_trips_per_s"] * step for run in objects_runs],
        "dds_bound_rcl_real_time_factor": bound_rcl,
        "dds_rcl_round_trip_us": 1e3 / bound_rcl,
        "dds_bound_rcl_before_after": [run["round_trips_per_s"] * step for run in rcl_runs],
        "pair_vs_rcl_bound": pair["stepping"] / bound_rcl,
        "controller_update_us_p50": latency["p50"],
        "controller_update_us_p99": latency["p99"],
        "controller_callback_us_p50": callback["p50"],
        "controller_callback_us_p99": callback["p99"],
        "controller_callback_us_p99_9": callback["p99_9"],
        "controller_callback_us_max": callback["max"],
        "pair_step_breakdown_us": breakdown,
        "node_work_us": [run["work"] for run in bare_runs],
        "scaling": scale,
        "sweep_runs_per_min": sweep["runs_per_min"],
        "sweep_parallel_efficiency": sweep["parallel_efficiency"],
        "optimize_trials_per_min": optimize_rate,
        "sweep": sweep,
        "bench_wall_time_s": time.monotonic() - started,
    }
    result["targets"] = target_figures(result, sweep)
    rows = [
        ("engine steps/s (paper model, voltage, RK4, 1 ms)", f"{engine:,.0f}"),
        ("MuJoCo steps/s (equivalent MJCF, RK4, 1 ms)", f"{mujoco:,.0f}" if mujoco else "n/a (mujoco not installed)"),
        ("engine / MuJoCo", f"{engine / mujoco:.3f}" if mujoco else "n/a"),
        (f"closed-loop rollout steps/s, paper model ({rollout_s:g} s runs)", f"{rollout:,.0f}"),
        (f"closed-loop rollout steps/s, hyper_7link ({rollout_s:g} s runs)", f"{rollout_hyper:,.0f}"),
        ("engine step alone, hyper_7link (1 V held) [us]", f"{hyper_step:.1f}"),
        ("Simulator.step (the Python face, its report as objects), paper [us]", f"{result['simulator_step_us']:.1f}"),
        (
            "links' distance queries' share of a step, ur5_table (target <= 0.20)",
            f"{collision['share']:.1%} ({collision['frame_step_us']:.1f} -> {collision['geometry_step_us']:.1f} us; "
            f"+{collision['bookkeeping_us']:.1f} us reporting)",
        ),
        ("pair real-time factor (lockstep stepping)", f"{pair['stepping']:.2f}"),
        ("pair real-time factor (whole run, with start-up)", f"{pair['whole_run']:.2f}"),
        ("the two nodes without the recorder: real-time factor", f"{without_recorder:.2f}"),
        ("recorder's share of a lockstep step (the pair with it against the two nodes alone)", f"{recorder_share:.1%}"),
        (
            "recorder's process CPU while the pair steps, per state [us]; over the recorded step",
            f"{pair['recorder_cpu_us_per_state']:.1f}; {pair['recorder_cpu_share']:.1%}",
        ),
        (
            f"timeline of a {duration:g} s run: startup / stepping / shutdown / report / whole [s]",
            " / ".join(f"{pair[k]:.2f}" for k in ("startup_s", "stepping_s", "shutdown_s", "report_s", "whole_run_s")),
        ),
        ("  command to first step (target < 1.5 s)", f"{pair['startup_s']:.2f} s"),
        ("  last step to last file written (target < 1.0 s)", f"{pair['last_step_to_last_file_s']:.2f} s"),
        (f"bracing-pair --duration {TINY_RUN_S:g}, command to exit (target < 2.5 s)", f"{tiny_command:.2f} s"),
        (
            f"make run / its {len(paper['runs'])} runs' stepping (target < 1.6)",
            f"{paper['ratio']:.2f} ({paper['whole_s']:.1f} s / {paper['stepping_s']:.1f} s)",
        ),
        ("DDS bound real-time factor (round trips/s x 1 ms, CDR bytes)", f"{bound:.2f}"),
        ("pair / bound", f"{result['pair_vs_bound']:.3f}"),
        ("DDS bound with rclpy message objects (for comparison)", f"{bound_objects:.2f}"),
        ("DDS bound without Python (C++ on rcl's C API), real-time factor", f"{bound_rcl:.2f}"),
        ("pair / rcl bound", f"{result['pair_vs_rcl_bound']:.3f}"),
        ("round trip [us]: rclpy, CDR bytes / C++ on rcl", f"{1e3 / bound:.1f} / {1e3 / bound_rcl:.1f}"),
        ("controller update p50 / p99 [us]", f"{latency['p50']:.1f} / {latency['p99']:.1f}"),
        (
            "controller node, its whole callback on a state in the pair, p50 / p99 / p99.9 / max [us]",
            " / ".join(f"{callback[key]:.1f}" for key in ("p50", "p99", "p99_9", "max"))
            + f"; to the command out p50 {callback['out_p50']:.1f}",
        ),
        ("a lockstep step [us per 1 ms step], where it goes:", f"{breakdown['step']:.0f}"),
        *((f"  {part.replace('_', ' ')}", f"{us:.1f}") for part, us in breakdown.items() if part != "step"),
    ]
    for p in (1, 2):
        s = scale[f"p{p}"]
        rates = ", ".join(f"n={n}: {v:,.0f}" for n, v in s["steps_per_s"].items())
        rows.append((f"scaling p={p} steps/s", f"{rates}; cost ~ n^{s['cost_exponent']:.2f}"))
    sweep_rates = ", ".join(f"{name}: {rate:.0f}" for name, rate in sweep["runs_per_min"].items())
    rows.append((f"sweep runs/min ({sweep['run_sim_time_s']:g} s runs)", sweep_rates))
    rows.append(("sweep parallel efficiency, 2 workers (target >= 0.9)", f"{sweep['parallel_efficiency']:.3f}"))
    rows.append(("optimiser trials/min (paper arm, 10 s runs, 2 workers)", f"{optimize_rate:.0f}"))
    rows.append(("speed figures (this run) against their targets:", ""))
    for key, value in result["targets"].items():
        rows.append((f"  {key.replace('_', ' ')} (target {TARGETS[key]})", "n/a" if value is None else f"{value:.3g}"))
    rows.append(("bench wall time", f"{result['bench_wall_time_s']:.0f} s"))
    return result, rows


if __name__ == "__main__":
    sys.exit(main())
