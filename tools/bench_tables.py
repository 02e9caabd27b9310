"""The Performance page's tables from a recorded ``make bench`` (docs/results/data/bench.json: bench/latest.json's
keys and its ``recorded`` provenance), rendered by tools/docs_reference.py. Each figure is read from the file;
the targets are bench/run.py's ``TARGETS`` and the page's own (``HEADLINE``)."""

from __future__ import annotations

import ast
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bracing_core.numbers import markdown_table

ROOT = Path(__file__).resolve().parents[1]


def bench_targets() -> dict[str, str]:
    """bench/run.py's ``TARGETS = {...}`` (a speed figure -> its target), read without importing the bench."""
    tree = ast.parse((ROOT / "bench" / "run.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "TARGETS" for t in node.targets):
            value: dict[str, str] = ast.literal_eval(node.value)
            return value
    raise SystemExit("bench/run.py: no `TARGETS = {...}` found")


def _n(value: float | None, digits: int = 3) -> str:
    """A figure to ``digits`` significant digits, thousands separated; n/a for null."""
    if value is None:
        return "n/a"
    if abs(value) >= 10**digits:
        return f"{value:,.0f}"
    return f"{value:.{digits}g}"


def headline_table(bench: dict[str, Any]) -> str:
    """The headline figures of one ``make bench``, each beside its target where the project set one."""
    b, sweep = bench, bench["sweep_runs_per_min"]
    rollout_s = b["rollout_sim_time_s"] / b["rollout_steps_per_s"] * 1000.0
    scaling = " / ".join(_n(rate) for rate in b["scaling"]["p1"]["steps_per_s"].values())
    rows = [
        ("engine, paper model, voltage, RK4, 1 ms, elbow braced: steps/s", _n(b["engine_steps_per_s"]), ""),
        ("MuJoCo, equivalent MJCF, RK4, 1 ms, in a Python loop: steps/s", _n(b["mujoco_steps_per_s"]), ""),
        ("**engine / MuJoCo**", _n(b["engine_vs_mujoco"]), ">= 2"),
        (
            f"closed-loop rollout (law + engine in C++), paper model: steps/s; a {b['rollout_sim_time_s']:g} s run",
            f"{_n(b['rollout_steps_per_s'])}; {_n(rollout_s)} s",
            "<= 0.15 s",
        ),
        (
            "hyper_7link: engine step [us]; rollout steps/s",
            f"{_n(b['engine_hyper_7link_step_us'])}; {_n(b['rollout_hyper_7link_steps_per_s'])}",
            "<= 40 us",
        ),
        ("`Simulator.step`, the Python face the node calls [us]", _n(b["simulator_step_us"]), ""),
        (
            "controller update in process, p50 / p99 [us]",
            f"{_n(b['controller_update_us_p50'])} / {_n(b['controller_update_us_p99'])}",
            "",
        ),
        (
            f"bracing-pair, lockstep, {b['pair_sim_time_s']:g} s, recorded: real-time factor; without the recorder",
            f"{_n(b['pair_real_time_factor'])}; {_n(b['pair_real_time_factor_no_recorder'])}",
            ">= 2.0 recorded",
        ),
        ("DDS bound (two processes ping-ponging the nodes' messages) x 1 ms", _n(b["dds_bound_real_time_factor"]), ""),
        (
            "DDS bound without Python (the same, two C++ processes on rcl's C API) x 1 ms; pair / it",
            f"{_n(b.get('dds_bound_rcl_real_time_factor'))}; {_n(b.get('pair_vs_rcl_bound'))}",
            "",
        ),
        (
            f"{b['pair_sim_time_s']:g} s paper run: command to first step; last step to last file",
            f"{_n(b['startup_s'])} s; {_n(b['last_step_to_last_file_s'])} s",
            "< 1.5 s; < 1.0 s",
        ),
        ("`bracing-pair --duration 0.01`, command to exit", f"{_n(b['tiny_run_command_s'])} s", "< 2.5 s"),
        (
            "sweep runs/min (10 s runs): 1 / 2 local workers, Dask LocalCluster (2)",
            " / ".join(_n(sweep[k]) for k in ("local_1", "local_2", "dask_local_2")),
            "",
        ),
        ("sweep parallel efficiency, 2 workers", _n(b["sweep_parallel_efficiency"]), ">= 0.9"),
        ("optimiser trials/min (paper arm, 10 s runs, 2 workers)", _n(b["optimize_trials_per_min"]), ""),
        ("scaling, generated chains, p = 1, n = 4 / 8 / 16 / 32 [steps/s]", scaling, ""),
    ]
    return markdown_table(["figure", "this `make bench`", "target"], rows)


def targets_table(bench: dict[str, Any]) -> str:
    """The speed figures (``targets`` of the file) beside bench/run.py's targets."""
    targets = bench_targets()
    rows = [(f"`{key}`", _n(value), targets.get(key, "")) for key, value in bench["targets"].items()]
    return markdown_table(["figure (a ratio of this run's figures)", "this `make bench`", "target"], rows)


STEP_PARTS = ("simulator_node", "engine", "controller_node", "law", "dds_round_trip", "recorder")
"""The parts of ``pair_step_breakdown_us`` that add up to its ``step`` (bench/run.py's step_breakdown_us)."""


def breakdown_table(bench: dict[str, Any]) -> str:
    """Where a recorded lockstep step's wall time goes (``pair_step_breakdown_us``): the parts that add up to
    the step, then the figures beside them (overlapping the other node, or the bound's)."""
    parts = bench["pair_step_breakdown_us"]
    rows = [(part.replace("_", " "), _n(parts[part])) for part in STEP_PARTS if part in parts]
    rows.append(("**a recorded step** (the sum)", f"**{_n(parts['step'])}**"))
    beside = [part for part in parts if part not in (*STEP_PARTS, "step")]
    rows += [(f"beside them: {part.replace('_', ' ')}", _n(parts[part])) for part in beside]
    return markdown_table(["part of a 1 ms step", "us"], rows)


SWEEP_EXECUTORS = {
    "local_1": "1 local worker process",
    "local_2": "2 local worker processes",
    "dask_local_2": "Dask LocalCluster, 2 single-threaded workers",
}
"""bench/sweep_bench.py's executors, as the page names them."""


def sweep_table(bench: dict[str, Any]) -> str:
    """The sweep's throughput per executor (``sweep``: medians of its repeats), its start-up apart, then the
    parallel efficiency of 2 local workers."""
    sweep = bench["sweep"]
    runs = sweep["runs"]
    sim = _n(sweep["run_sim_time_s"])
    rows = [
        (name, _n(sweep["runs_per_min"][key]), f"{_n(sweep['mean_run_s'][key])} s", f"{_n(sweep['startup_s'][key])} s")
        for key, name in SWEEP_EXECUTORS.items()
        if key in sweep["runs_per_min"]
    ]
    rows.append(("**parallel efficiency, 2 local workers**", f"**{_n(sweep['parallel_efficiency'])}**", "", ""))
    header = [f"executor ({runs} runs of {sim} s)", "runs/min", "mean wall time of one run", "start-up"]
    return markdown_table(header, rows)


TABLES: dict[str, Callable[[dict[str, Any]], str]] = {
    "headline": headline_table,
    "targets": targets_table,
    "breakdown": breakdown_table,
    "sweep": sweep_table,
}
