"""make run's three runs through reused processes: one simulator (``wait_for_reset``), one controller and one
recorder (``--stay``) make the braced run, then (``bracing`` set false on both nodes, reset_simulation) the
passive one, then (``free_space`` set true) the free-space one. Each bag equals the bag fresh processes started
with those parameters record, message for message (the controller's compute_time, a wall time, aside). While
running, both nodes refuse a change that needs a fresh start (``robot.urdf``), with the reason."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from ros_helpers import PAPER_YAML, REPO_ROOT, isolated_env
from test_recorder_bag_switch import raw_bag, set_recorder
from test_recorder_report import Proc
from test_reused_runs import DURATION_S, RESET, wait_for, wall_time_zeroed, wrote

from bracing_bringup.run_plan import PARAMS_FILE, RunOptions, RunPlan, plan_run, write_params
from bracing_core.overrides import SIMULATOR
from bracing_core.variants import BRACED, PASSIVE, RUNS, Variant

NODES = ("/bracing_simulator", "/bracing_controller")
SET_PARAMETERS = """
import json, sys
import rclpy
from rclpy.parameter import Parameter
from rcl_interfaces.srv import SetParameters
rclpy.init()
node = rclpy.create_node("reused_variants_test")
results = {}
for name, values in json.loads(sys.argv[1]).items():
    client = node.create_client(SetParameters, name + "/set_parameters")
    assert client.wait_for_service(timeout_sec=30.0), "no parameter service of " + name
    request = SetParameters.Request()
    request.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
    for attempt in range(10):  # a set is idempotent: asked again if Fast DDS dropped its response (unmatched)
        future = client.call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=3.0)
        if future.done():
            break
    results[name] = [[r.successful, r.reason] for r in future.result().results]
print(json.dumps(results))
"""


def comparable(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    """The bag's messages with their wall times zeroed: each controller_state's compute_time, and each run_status
    warning's wall_time (when it was said)."""
    import dataclasses

    from bracing_core.typestore import RUN_STATUS, bracing_typestore

    store, messages = bracing_typestore(), wall_time_zeroed(raw_bag(bag))

    def zeroed(data: bytes) -> bytes:
        msg = store.deserialize_cdr(data, RUN_STATUS)
        msg = dataclasses.replace(msg, wall_time=dataclasses.replace(msg.wall_time, sec=0, nanosec=0))
        return bytes(store.serialize_cdr(msg, RUN_STATUS))

    if "/run_status" in messages:
        messages["/run_status"] = [(stamp, zeroed(data)) for stamp, data in messages["/run_status"]]
    return messages


def set_parameters(env: dict[str, str], values: dict[str, dict[str, Any]]) -> dict[str, list[list[Any]]]:
    """Set each node's parameters (``ros2 param set``'s service); node -> [[successful, reason], ...]."""
    done = subprocess.run(
        [sys.executable, "-c", SET_PARAMETERS, json.dumps(values)], env=env, capture_output=True, text=True, timeout=90
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def plan_of(variant: Variant, out: Path, parameters: dict[str, Any]) -> RunPlan:
    """The pair's plan of ``variant``'s run into ``out`` (its params file written there; ``parameters``: --set),
    the simulator staying at the run's end for a reset."""
    options = RunOptions(PAPER_YAML, out, duration=DURATION_S, bracing=variant.bracing, free_space=variant.free_space)
    options.parameters = dict(parameters)
    plan = plan_run(options)
    params = plan.node_params
    params[SIMULATOR] |= {"wait_for_reset": True, "min_status_subscribers": 1}  # the recorder: no bracing-pair here
    out.mkdir(parents=True)
    write_params(out / PARAMS_FILE, params)
    return plan


def stop(procs: list[subprocess.Popen[Any]]) -> list[int]:
    """SIGINT each (simulator first), their exit codes."""
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    codes = []
    for proc in procs:
        try:
            codes.append(proc.wait(timeout=30))
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGUSR1)  # every thread's stack into its log (report_faults): where it hung
            time.sleep(1.0)
            proc.kill()
            codes.append(proc.wait())
    return codes


def record_runs(
    tmp_path: Path,
    variants: tuple[Variant, ...],
    refused: dict[str, Any] | None = None,
    parameters: dict[str, Any] | None = None,
) -> list[Path]:
    """``variants`` run in turn by one simulator, controller and recorder (``tmp_path``: their logs), each next
    one's per-run parameters set on both nodes before its reset if they change; their bags, each with every state.
    ``refused``: a change asked of both nodes after the first run (each node's answer kept in it under "answers");
    ``parameters``: the scenario's --set."""
    outs = [tmp_path / f"{k}_{variant.name}" for k, variant in enumerate(variants)]
    plans = [plan_of(variant, out, parameters or {}) for variant, out in zip(variants, outs, strict=True)]
    recorder, controller, simulator = plans[0].processes(outs[0])
    env = isolated_env()
    rec = Proc([*recorder.argv(), "--stay"], env)
    logs = {name: (tmp_path / f"{name}.log").open("w") for name in ("controller", "simulator")}
    nodes = [
        subprocess.Popen(p.argv(), env=env, stdout=logs[p.name], stderr=subprocess.STDOUT, cwd=REPO_ROOT)
        for p in (controller, simulator)
    ]
    try:
        wait_for(rec, wrote(outs[0] / "bag"), 120.0)
        if refused is not None:
            refused["answers"] = set_parameters(env, {node: refused["change"] for node in NODES})
        for before, variant, out in zip(variants, variants[1:], outs[1:], strict=False):
            per_run = {"bracing": variant.bracing, "free_space": variant.free_space}
            if per_run != {"bracing": before.bracing, "free_space": before.free_space}:  # else a reset alone
                answers = set_parameters(env, dict.fromkeys(NODES, per_run))
                assert answers == {node: [[True, ""], [True, ""]] for node in NODES}, answers
            asked = {"output": str(out / "bag"), "params_files": [str(out / PARAMS_FILE)]}
            assert set_recorder(env, asked) == (True, "")
            wait_for(rec, lambda line: line == "recorder ready", 30.0)
            reset = subprocess.run([sys.executable, "-c", RESET], env=env, capture_output=True, text=True, timeout=90)
            assert reset.returncode == 0, reset.stderr[-2000:]
            wait_for(rec, wrote(out / "bag"), 120.0)
    finally:
        codes = stop([nodes[1], nodes[0], rec.popen])
        for log in logs.values():
            log.close()
    sim_log = (tmp_path / "simulator.log").read_text()
    assert codes == [0, 0, 0], f"{codes}\n{sim_log[-3000:]}\n{(tmp_path / 'controller.log').read_text()[-3000:]}"
    for out, plan in zip(outs, plans, strict=True):
        bag = raw_bag(out / "bag")
        assert len(bag["/joint_states"]) == len(bag["/tf"]) == plan.expected_states, out
    return [out / "bag" for out in outs]


def test_make_run_s_three_runs_through_reused_processes_record_the_bags_of_fresh_runs(tmp_path: Path) -> None:
    refused: dict[str, Any] = {"change": {"robot.urdf": "another.urdf"}}
    reused = record_runs(tmp_path / "reused", RUNS, refused)
    reason = (
        "robot.urdf: cannot change while running: it needs a fresh start (a new {} process started with the new value)"
    )
    assert refused["answers"] == {node: [[False, reason.format(node.removeprefix("/bracing_"))]] for node in NODES}, (
        refused["answers"]
    )
    sim_log = (tmp_path / "reused" / "simulator.log").read_text()
    assert sim_log.count("reset_simulation: back to the initial state at t = 0.000000 s") == 2
    assert "from the next run (reset_simulation): bracing = False" in sim_log  # one line per parameter set
    assert "from the next run (reset_simulation): free_space = True" in sim_log
    ctl_log = (tmp_path / "reused" / "controller.log").read_text()
    assert ctl_log.count("joint_states went back in time") == 2
    bags = {}
    for variant, bag in zip(RUNS, reused, strict=True):
        fresh = record_runs(tmp_path / f"fresh_{variant.name}", (variant,))[0]
        bags[variant.name] = comparable(bag)
        assert bags[variant.name] == comparable(fresh), variant.name  # every topic, every message
    assert bags["passive"]["/controller_state"] != bags["braced"]["/controller_state"]  # three runs, not one thrice
    assert bags["free_space"]["/contacts"] != bags["passive"]["/contacts"]


def test_a_passive_run_then_a_braced_one_with_force_feedback_records_the_bags_of_fresh_runs(tmp_path: Path) -> None:
    """The next run reads force reports the run before did not: the controller subscribes to them for it, in time
    for the first report (else that state waits for it and is warned about, as a fresh controller's is not)."""
    feedback = {"contacts.elbow.force_feedback.kp": 0.3, "contacts.elbow.force_feedback.ki": 50.0}
    runs = (PASSIVE, BRACED)
    reused = record_runs(tmp_path / "reused", runs, parameters=feedback)
    ctl_log = (tmp_path / "reused" / "controller.log").read_text()
    assert "no report of the last step" not in ctl_log
    for variant, bag in zip(runs, reused, strict=True):
        fresh = record_runs(tmp_path / f"fresh_{variant.name}", (variant,), parameters=feedback)[0]
        assert comparable(bag) == comparable(fresh), variant.name
